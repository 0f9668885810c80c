// STL, binary (80-byte header, uint32 count, 50 bytes per facet) and ascii ('solid ...
// facet ... vertex x y z ... endsolid', keywords in any case). Facets keep their own
// three corners in the file; corners at one position become one vertex here.
#include <cstdint>
#include <cstring>

#include "dentmark/common/ingest/detail/readers.h"
#include "text_cursor.h"

namespace dentmark::ingest::detail {
namespace {

// Binary when the header's facet count gives exactly the file's size.
bool looks_binary(std::string_view b) {
  if (b.size() < 84) return false;
  std::uint32_t n = 0;
  std::memcpy(&n, b.data() + 80, 4);
  return 84 + 50ull * n == b.size();
}

// A word equal to a lower-case keyword, in any case ("SOLID", "EndLoop").
bool is(std::string_view word, std::string_view keyword) {
  if (word.size() != keyword.size()) return false;
  for (std::size_t i = 0; i < word.size(); ++i) {
    const char c = word[i] >= 'A' && word[i] <= 'Z' ? static_cast<char>(word[i] - 'A' + 'a') : word[i];
    if (c != keyword[i]) return false;
  }
  return true;
}

bool space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n';
}

// The first byte no text file holds (a control character other than tab and the
// newlines, or DEL), or npos. UTF-8 in a solid's name is text.
std::size_t first_non_text(std::string_view b) {
  for (std::size_t i = 0; i < b.size(); ++i) {
    const auto c = static_cast<unsigned char>(b[i]);
    if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r') || c == 0x7f) return i;
  }
  return std::string_view::npos;
}

[[noreturn]] void neither(const std::string& path, std::string_view bytes, std::size_t at,
                          const std::string& why) {
  std::string binary = "too short for a binary STL";
  if (bytes.size() >= 84) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    binary = "its header's " + std::to_string(n) + " facets need " + std::to_string(84 + 50ull * n) +
             " bytes, the file has " + std::to_string(bytes.size());
  }
  throw IngestError(path + ": byte " + std::to_string(at) + ": neither a binary STL of matching size (" +
                    binary + ") nor ASCII STL (" + why + ")");
}

}  // namespace

Mesh read_stl(const std::string& path, std::string_view bytes) {
  Mesh mesh;
  if (looks_binary(bytes)) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    mesh.vertices.resize(3ull * n);
    mesh.triangles.resize(n);
    const char* base = bytes.data() + 84;
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
      float v[9];
      std::memcpy(v, base + 50 * i + 12, sizeof v);  // skip the facet normal
      for (int k = 0; k < 3; ++k) {
        mesh.vertices[3 * i + k] = Eigen::Vector3f(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
      }
      const auto b = static_cast<std::uint32_t>(3 * i);
      mesh.triangles[i] = {b, b + 1, b + 2};
    }
    weld_vertices(mesh);
    return mesh;
  }
  // ASCII: 'solid' first (after a byte order mark and blanks, in any case), text throughout.
  std::size_t start = bytes.starts_with("\xEF\xBB\xBF") ? 3 : 0;
  while (start < bytes.size() && space(bytes[start])) ++start;
  if (!is(bytes.substr(start, 5), "solid")) neither(path, bytes, start, "no 'solid' at the start");
  if (const std::size_t at = first_non_text(bytes); at != std::string_view::npos)
    neither(path, bytes, at, "a binary byte after 'solid'");

  // solid [name] { facet normal n n n / outer loop / vertex x y z (3 times) / endloop /
  // endfacet } endsolid [name], as often as the file holds solids.
  enum class State { kOutside, kSolid, kFacet, kLoop, kLoopDone };
  State state = State::kOutside;
  int corners = 0;
  std::size_t last_line = 1;
  TextCursor cur(path, bytes);
  const auto expected = [&](std::string_view key) {
    static constexpr const char* kWanted[] = {"'solid'", "'facet' or 'endsolid'", "'outer loop'",
                                              "'vertex' or 'endloop'", "'endfacet'"};
    cur.fail("'" + std::string(key.substr(0, 32)) + "' where " + kWanted[static_cast<int>(state)] +
             " belongs in ascii STL");
  };
  while (true) {
    cur.skip_space();
    if (cur.at_end()) break;
    last_line = cur.line();
    const std::string_view key = cur.word();
    if (is(key, "solid")) {
      if (state != State::kOutside) expected(key);
      state = State::kSolid;
    } else if (is(key, "endsolid")) {
      if (state != State::kSolid) expected(key);
      state = State::kOutside;
    } else if (is(key, "facet")) {
      if (state != State::kSolid) expected(key);
      state = State::kFacet;
    } else if (is(key, "outer")) {
      if (state != State::kFacet || !is(cur.word(), "loop")) expected(key);
      state = State::kLoop;
      corners = 0;
    } else if (is(key, "vertex")) {
      if (state != State::kLoop) expected(key);
      if (corners == 3) cur.fail("a fourth 'vertex' in a facet (a facet has 3)");
      const double x = cur.number("x"), y = cur.number("y"), z = cur.number("z");
      mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
      ++corners;
    } else if (is(key, "endloop")) {
      if (state != State::kLoop) expected(key);
      if (corners != 3) cur.fail("facet loop with " + std::to_string(corners) + " vertices (a facet has 3)");
      const auto b = static_cast<std::uint32_t>(mesh.vertices.size() - 3);
      mesh.triangles.push_back({b, b + 1, b + 2});
      state = State::kLoopDone;
    } else if (is(key, "endfacet")) {
      if (state != State::kLoopDone) expected(key);
      state = State::kSolid;
    } else {
      expected(key);
    }
    cur.next_line();
  }
  if (state == State::kSolid)
    throw IngestError(path + ": line " + std::to_string(last_line) +
                      ": the file ends here with no 'endsolid' after the last facet: is it cut short?");
  if (state != State::kOutside)
    throw IngestError(path + ": line " + std::to_string(last_line) + ": the file ends inside a facet");
  weld_vertices(mesh);
  return mesh;
}

}  // namespace dentmark::ingest::detail
