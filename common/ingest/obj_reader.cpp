// Wavefront OBJ: 'v x y z [w]' and 'f a[/t[/n]] b c ...' (1-based, negative = relative);
// polygons are triangulated as fans; every other statement is skipped.
#include <vector>

#include "dentmark/common/ingest/detail/readers.h"
#include "text_cursor.h"

namespace dentmark::ingest::detail {

Mesh read_obj(const std::string& path, std::string_view bytes) {
  Mesh mesh;
  TextCursor cur(path, bytes);
  std::vector<std::uint32_t> corners;
  while (true) {
    cur.skip_space();
    if (cur.at_end()) break;
    const std::string_view key = cur.word();
    if (key == "v") {
      const double x = cur.number("x"), y = cur.number("y"), z = cur.number("z");
      mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    } else if (key == "f") {
      corners.clear();
      while (!cur.at_eol()) {
        const long long i = cur.integer("face vertex index");
        const long long n = static_cast<long long>(mesh.vertices.size());
        const long long k = i > 0 ? i - 1 : n + i;
        if (i == 0 || k < 0 || k >= n)
          cur.fail("vertex index " + std::to_string(i) + " out of range (" + std::to_string(n) +
                   " vertices so far)");
        corners.push_back(static_cast<std::uint32_t>(k));
        // Skip the corner's '/t/n' parts, if any ("7", "7/3", "7//5", "7/3/5").
        if (!cur.at_end() && *cur.pos() == '/') {
          cur.word();
        } else if (!cur.at_end() && *cur.pos() != ' ' && *cur.pos() != '\t' && *cur.pos() != '\r' &&
                   *cur.pos() != '\n') {
          cur.fail("bad face corner");
        }
      }
      // A face has at least 3 corners; fewer is a malformed (or cut) statement, not a face
      // to drop quietly ('l' is the statement for lines).
      if (corners.size() < 3)
        cur.fail("face with " + std::to_string(corners.size()) + " corners (a face needs at least 3)");
      for (std::size_t k = 1; k + 1 < corners.size(); ++k)
        mesh.triangles.push_back({corners[0], corners[k], corners[k + 1]});
    }
    cur.next_line();
  }
  if (mesh.vertices.empty()) throw IngestError(path + ": line 1: no 'v' vertices in the OBJ file");
  return mesh;
}

}  // namespace dentmark::ingest::detail
