// XYZ text point clouds: 'x y z [more columns]' per line, separated by blanks or
// commas; '#' lines are comments.
#include "readers.h"
#include "text_cursor.h"

namespace dentmark::ingest::detail {

Mesh read_xyz(const std::string& path, std::string_view bytes) {
  Mesh mesh;
  mesh.vertices.reserve(bytes.size() / 24);
  TextCursor cur(path, bytes);
  while (true) {
    cur.skip_space();
    if (cur.at_end()) break;
    if (*cur.pos() == '#' || *cur.pos() == '/') {
      cur.next_line();
      continue;
    }
    const double x = cur.number("x"), y = cur.number("y"), z = cur.number("z");
    mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    cur.next_line();
  }
  if (mesh.vertices.empty()) throw IngestError(path + ": line 1: no points in the XYZ file");
  return mesh;
}

}  // namespace dentmark::ingest::detail
