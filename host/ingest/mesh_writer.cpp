#include "dentmark/host/ingest/mesh_writer.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

namespace dentmark::ingest {

void write_ply(const std::string& path, const MeshView& mesh,
               const std::vector<std::array<std::uint8_t, 3>>& colours) {
  const bool coloured = colours.size() == mesh.vertex_count() && !colours.empty();
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw IngestError(path + ": cannot write: " + std::strerror(errno));
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment dentmark, units: m\nelement vertex " +
                       std::to_string(mesh.vertex_count()) +
                       "\nproperty float x\nproperty float y\nproperty float z\n";
  if (coloured) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header += "element face " + std::to_string(mesh.triangle_count()) +
            "\nproperty list uchar int vertex_indices\nend_header\n";
  bool good = std::fwrite(header.data(), 1, header.size(), f) == header.size();
  const std::size_t vstride = coloured ? 15 : 12;
  std::vector<char> buf;
  buf.reserve(1 << 20);
  auto flush = [&] {
    if (!buf.empty()) good = good && std::fwrite(buf.data(), 1, buf.size(), f) == buf.size();
    buf.clear();
  };
  for (std::size_t i = 0; i < mesh.vertex_count(); ++i) {
    char rec[15];
    const Eigen::Vector3f v = mesh.vertex(i);
    std::memcpy(rec, v.data(), 12);
    if (coloured) std::memcpy(rec + 12, colours[i].data(), 3);
    buf.insert(buf.end(), rec, rec + vstride);
    if (buf.size() > (1 << 20)) flush();
  }
  for (std::size_t i = 0; i < mesh.triangle_count(); ++i) {
    const auto t = mesh.triangle(i);
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
