// XYZ text point clouds (.xyz, .txt, .pts, .asc, .csv): 'x y z [more columns]' per line.
// As tools write them:
//  * separated by blanks, commas or semicolons; a file whose first line writes its
//    numbers with a decimal comma (a spreadsheet in such a locale: "1,25;0,5;2") takes
//    the comma for the decimal mark throughout;
//  * '#' and '/' lines are comments; the first line may instead be a header: column
//    names ("X,Y,Z,Nx,Ny,Nz") or a point count (Leica .pts). It is the header when it
//    holds fewer than three numbers; any later such line is an error naming it.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <string>

#include "dentmark/common/ingest/detail/readers.h"
#include "text_cursor.h"

namespace dentmark::ingest::detail {
namespace {

// Whether the line writes its numbers with a decimal comma: it splits at blanks or
// semicolons into three or more fields, none with more than one comma, and every comma
// stands between digits ("1,25;0,5;2", "1,25\t0,5\t2"; not "1.5,2.5,3.5" nor "1, 2, 3").
bool decimal_comma_line(std::string_view line) {
  int fields = 0, commas = 0;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r' || line[i] == ';')) ++i;
    if (i >= line.size()) break;
    const std::size_t b = i;
    int in_field = 0;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r' && line[i] != ';') {
      if (line[i] == ',') {
        const bool between_digits = i > b && i + 1 < line.size() &&
                                    std::isdigit(static_cast<unsigned char>(line[i - 1])) &&
                                    std::isdigit(static_cast<unsigned char>(line[i + 1]));
        if (!between_digits || ++in_field > 1) return false;
      }
      ++i;
    }
    ++fields, commas += in_field;
  }
  return fields >= 3 && commas > 0;
}

// The line's first three numbers, separators ' ', '\t', ';' and (unless it is the
// decimal mark) ','. False if it does not start with three numbers.
bool three_numbers(std::string_view line, bool decimal_comma, double out[3]) {
  std::string buf;
  if (decimal_comma) {  // from_chars reads '.' only
    buf.assign(line);
    std::replace(buf.begin(), buf.end(), ',', '.');
    line = buf;
  }
  const char* p = line.data();
  const char* end = p + line.size();
  const auto separator = [&](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == ';' || (!decimal_comma && c == ',');
  };
  for (int i = 0; i < 3; ++i) {
    while (p < end && separator(*p)) ++p;
    if (p < end && *p == '+') ++p;
    auto r = std::from_chars(p, end, out[i]);
    if (r.ec == std::errc::result_out_of_range)  // denormals and huge values: as strtod
      out[i] = std::strtod(std::string(p, static_cast<std::size_t>(r.ptr - p)).c_str(), nullptr);
    else if (r.ec != std::errc())
      return false;
    if (r.ptr < end && !separator(*r.ptr)) return false;  // "1.5x": not a number
    p = r.ptr;
  }
  return true;
}

}  // namespace

Mesh read_xyz(const std::string& path, std::string_view bytes) {
  Mesh mesh;
  mesh.vertices.reserve(bytes.size() / 24);
  TextCursor cur(path, bytes);
  bool first = true, decimal_comma = false;
  while (true) {
    cur.skip_space();
    if (cur.at_end()) break;
    if (*cur.pos() == '#' || *cur.pos() == '/') {
      cur.next_line();
      continue;
    }
    const char* b = cur.pos();
    const std::size_t line = cur.line();
    cur.next_line();
    std::string_view text(b, static_cast<std::size_t>(cur.pos() - b));
    if (!text.empty() && text.back() == '\n') text.remove_suffix(1);
    if (mesh.vertices.empty()) decimal_comma = decimal_comma_line(text);  // decided by the first point
    double p[3];
    if (!three_numbers(text, decimal_comma, p)) {
      if (first && mesh.vertices.empty()) {  // a header: column names or a point count
        first = false;
        continue;
      }
      throw IngestError(path + ": line " + std::to_string(line) + ": expected three numbers x y z");
    }
    first = false;
    mesh.vertices.emplace_back(static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]));
  }
  if (mesh.vertices.empty()) throw IngestError(path + ": line 1: no points in the XYZ file");
  return mesh;
}

}  // namespace dentmark::ingest::detail
