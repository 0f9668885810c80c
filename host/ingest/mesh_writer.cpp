#include "dentmark/host/ingest/mesh_writer.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

namespace dentmark::ingest {

void write_ply(const std::string& path, const Mesh& mesh,
               const std::vector<std::array<std::uint8_t, 3>>& colours) {
  const bool coloured = colours.size() == mesh.vertices.size() && !colours.empty();
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw IngestError(path + ": cannot write: " + std::strerror(errno));
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment dentmark, units: m\nelement vertex " +
                       std::to_string(mesh.vertices.size()) +
                       "\nproperty float x\nproperty float y\nproperty float z\n";
  if (coloured) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header += "element face " + std::to_string(mesh.triangles.size()) +
            "\nproperty list uchar int vertex_indices\nend_header\n";
  bool good = std::fwrite(header.data(), 1, header.size(), f) == header.size();
  const std::size_t vstride = coloured ? 15 : 12;
  std::vector<char> buf;
  buf.reserve(1 << 20);
  auto flush = [&] {
    if (!buf.empty()) good = good && std::fwrite(buf.data(), 1, buf.size(), f) == buf.size();
    buf.clear();
  };
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    char rec[15];
    std::memcpy(rec, mesh.vertices[i].data(), 12);
    if (coloured) std::memcpy(rec + 12, colours[i].data(), 3);
    buf.insert(buf.end(), rec, rec + vstride);
    if (buf.size() > (1 << 20)) flush();
  }
  for (const auto& t : mesh.triangles) {
    char rec[13];
    rec[0] = 3;
    std::memcpy(rec + 1, t.data(), 12);
    buf.insert(buf.end(), rec, rec + 13);
    if (buf.size() > (1 << 20)) flush();
  }
  flush();
  good = (std::fclose(f) == 0) && good;
  if (!good) {
    std::remove(tmp.c_str());
    throw IngestError(path + ": write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw IngestError(path + ": cannot rename the temporary file: " + ec.message());
  }
}

}  // namespace dentmark::ingest
