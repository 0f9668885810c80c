// PCD, the Point Cloud Library's format (v0.5–0.7): a text header of keyword lines
//   VERSION, FIELDS (COLUMNS in v0.5), SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT,
//   POINTS, DATA ascii | binary | binary_compressed
// ('#' lines are comments), then the points:
//   ascii              one point a line, every field's COUNT values in FIELDS order;
//   binary             records of sum(SIZE * COUNT) bytes, fields in order, little-endian
//                      (PCL pads the file to a whole memory page: what follows is not read);
//   binary_compressed  uint32 compressed size, uint32 uncompressed size, then LZF of the
//                      same bytes laid out field by field (all points' x, then all y, ...).
// x, y and z (any numeric TYPE and SIZE) are read; normals, colours, curvature and PCL's
// '_' padding fields are skipped. An organised cloud (HEIGHT > 1, a point per sensor
// pixel) keeps its NaN points for holes: the caller meshes the finite ones.
#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <vector>

#include "dentmark/common/ingest/detail/readers.h"
#include "lzf.h"
#include "text_cursor.h"

namespace dentmark::ingest::detail {
namespace {

constexpr const char* kAxis[3] = {"x", "y", "z"};

struct Field {
  std::string name;
  std::size_t size = 4;  // bytes of one value
  char type = 'F';       // I signed, U unsigned, F floating point
  std::size_t count = 1;
};

enum class Data { kAscii, kBinary, kCompressed };

struct PcdHeader {
  std::vector<Field> fields;
  std::uint64_t width = 0, height = 1, points = 0;
  Data data = Data::kAscii;
  std::size_t body = 0;                // byte offset of the first point
  std::size_t data_line = 0;           // line of 'DATA'
  std::array<int, 3> xyz{-1, -1, -1};  // field index of x, y, z
};

// One line's values for a per-field keyword (SIZE, TYPE, COUNT): as many as FIELDS.
std::vector<std::string_view> per_field_words(TextCursor& cur, std::string_view key, std::size_t fields) {
  if (fields == 0) cur.fail("'" + std::string(key) + "' before 'FIELDS'");
  std::vector<std::string_view> words;
  while (!cur.at_eol()) words.push_back(cur.word());
  if (words.size() != fields)
    cur.fail("'" + std::string(key) + "' has " + std::to_string(words.size()) + " values for " +
             std::to_string(fields) + " fields");
  return words;
}

std::uint64_t header_count(TextCursor& cur, const char* what) {
  const long long n = cur.integer(what);
  if (n < 0 || static_cast<unsigned long long>(n) > std::numeric_limits<std::uint32_t>::max())
    cur.fail(std::string(what) + " " + std::to_string(n) + " out of range (0 to 2^32 - 1)");
  return static_cast<std::uint64_t>(n);
}

// The header's keywords seen so far that are required, or change a default.
struct HeaderSeen {
  bool size = false, type = false, width = false, points = false;
};

// SIZE: each field's bytes, 1, 2, 4 or 8.
void read_sizes(TextCursor& cur, PcdHeader& h) {
  const auto words = per_field_words(cur, "SIZE", h.fields.size());
  for (std::size_t f = 0; f < words.size(); ++f) {
    if (words[f] != "1" && words[f] != "2" && words[f] != "4" && words[f] != "8")
      cur.fail("field '" + h.fields[f].name + "': SIZE '" + std::string(words[f]) + "' (1, 2, 4 or 8)");
    h.fields[f].size = static_cast<std::size_t>(words[f][0] - '0');
  }
}

// TYPE: each field's I (signed), U (unsigned) or F (floating point).
void read_types(TextCursor& cur, PcdHeader& h) {
  const auto words = per_field_words(cur, "TYPE", h.fields.size());
  for (std::size_t f = 0; f < words.size(); ++f) {
    if (words[f] != "I" && words[f] != "U" && words[f] != "F")
      cur.fail("field '" + h.fields[f].name + "': TYPE '" + std::string(words[f]) + "' (I, U or F)");
    h.fields[f].type = words[f][0];
  }
}

// COUNT: each field's values a point, 1 to 65536.
void read_counts(TextCursor& cur, PcdHeader& h) {
  const auto words = per_field_words(cur, "COUNT", h.fields.size());
  for (std::size_t f = 0; f < words.size(); ++f) {
    std::size_t n = 0;
    const auto r = std::from_chars(words[f].data(), words[f].data() + words[f].size(), n);
    if (r.ec != std::errc() || r.ptr != words[f].data() + words[f].size() || n < 1 || n > 65536)
      cur.fail("field '" + h.fields[f].name + "': COUNT '" + std::string(words[f]) + "' (1 to 65536)");
    h.fields[f].count = n;
  }
}

// DATA, the header's last line: the body's encoding and where it starts.
void read_data_line(TextCursor& cur, std::string_view bytes, PcdHeader& h) {
  h.data_line = cur.line();
  const std::string_view d = cur.word();
  if (d == "ascii")
    h.data = Data::kAscii;
  else if (d == "binary")
    h.data = Data::kBinary;
  else if (d == "binary_compressed")
    h.data = Data::kCompressed;
  else
    cur.fail("DATA '" + std::string(d) + "' (ascii, binary or binary_compressed)");
  if (!cur.at_eol()) cur.fail("extra words after 'DATA " + std::string(d) + "'");
  cur.next_line();
  h.body = static_cast<std::size_t>(cur.pos() - bytes.data());
}

// One keyword line (the cursor at its keyword) into h; false on DATA, the last line.
// Fails naming the line on an unknown keyword, a bad value or extra values.
bool read_header_line(TextCursor& cur, std::string_view bytes, PcdHeader& h, HeaderSeen& seen) {
  const std::string_view key = cur.word();
  if (key == "VERSION") {
    cur.word();
  } else if (key == "FIELDS" || key == "COLUMNS") {
    if (!h.fields.empty()) cur.fail("a second 'FIELDS' line");
    while (!cur.at_eol()) h.fields.push_back(Field{std::string(cur.word())});
    if (h.fields.empty()) cur.fail("'FIELDS' names no field");
  } else if (key == "SIZE") {
    read_sizes(cur, h);
    seen.size = true;
  } else if (key == "TYPE") {
    read_types(cur, h);
    seen.type = true;
  } else if (key == "COUNT") {
    read_counts(cur, h);
  } else if (key == "WIDTH") {
    h.width = header_count(cur, "WIDTH");
    seen.width = true;
  } else if (key == "HEIGHT") {
    h.height = header_count(cur, "HEIGHT");
  } else if (key == "VIEWPOINT") {
    for (int k = 0; k < 7; ++k) cur.number("VIEWPOINT (tx ty tz qw qx qy qz)");
  } else if (key == "POINTS") {
    h.points = header_count(cur, "POINTS");
    seen.points = true;
  } else if (key == "DATA") {
    read_data_line(cur, bytes, h);
    return false;
  } else {
    cur.fail("unknown PCD header keyword '" + std::string(key.substr(0, 32)) + "'");
  }
  if (!cur.at_eol()) cur.fail("extra values after '" + std::string(key) + "'");
  cur.next_line();
  return true;
}

// The header as a whole, once DATA is read: the required lines were there, the sizes and
// counts agree, and x, y and z are fields of one value each (their indices into h.xyz).
// Fails naming the DATA line.
void check_header(const std::string& path, const HeaderSeen& seen, PcdHeader& h) {
  const auto fail = [&](const std::string& problem) {
    throw IngestError(path + ": line " + std::to_string(h.data_line) + ": " + problem);
  };
  if (h.fields.empty()) fail("no 'FIELDS' line before 'DATA'");
  if (!seen.size) fail("no 'SIZE' line before 'DATA'");
  if (!seen.type) fail("no 'TYPE' line before 'DATA'");
  for (const Field& f : h.fields)
    if (f.type == 'F' && f.size != 4 && f.size != 8)
      fail("field '" + f.name + "': TYPE F with SIZE " + std::to_string(f.size) + " (4 or 8)");
  std::size_t record = 0;
  for (const Field& f : h.fields) record += f.size * f.count;
  if (record > (1u << 20)) fail("a point of " + std::to_string(record) + " bytes (at most 1 MiB)");
  if (!seen.width) fail("no 'WIDTH' line before 'DATA'");
  if (h.width * h.height > std::numeric_limits<std::uint32_t>::max() - 1)
    fail("WIDTH x HEIGHT " + std::to_string(h.width) + " x " + std::to_string(h.height) +
         ": at most 2^32 - 2 points are supported");
  if (!seen.points) h.points = h.width * h.height;
  if (h.points != h.width * h.height)
    fail("POINTS " + std::to_string(h.points) + " is not WIDTH x HEIGHT = " + std::to_string(h.width) +
         " x " + std::to_string(h.height));
  for (std::size_t f = 0; f < h.fields.size(); ++f)
    for (int a = 0; a < 3; ++a)
      if (h.fields[f].name == kAxis[a]) {
        if (h.xyz[a] >= 0) fail("a second field '" + h.fields[f].name + "'");
        if (h.fields[f].count != 1)
          fail("field '" + h.fields[f].name + "' has COUNT " + std::to_string(h.fields[f].count) + " (1)");
        h.xyz[a] = static_cast<int>(f);
      }
  for (int a = 0; a < 3; ++a)
    if (h.xyz[a] < 0) fail(std::string("no field '") + kAxis[a] + "' in FIELDS");
}

// The header's keyword lines ('#' lines are comments) up to DATA, then checked whole.
PcdHeader parse_header(const std::string& path, std::string_view bytes) {
  PcdHeader h;
  HeaderSeen seen;
  TextCursor cur(path, bytes);
  while (true) {
    cur.skip_space();
    if (cur.at_end()) cur.fail("the header ends without a 'DATA' line");
    if (*cur.pos() == '#') {
      cur.next_line();
      continue;
    }
    if (!read_header_line(cur, bytes, h, seen)) break;
  }
  check_header(path, seen, h);
  return h;
}

template <typename U>
U from_little_endian(U v) {
  if constexpr (std::endian::native == std::endian::little || sizeof(U) == 1) return v;
  if constexpr (sizeof(U) == 2) return static_cast<U>(__builtin_bswap16(v));
  if constexpr (sizeof(U) == 4) return static_cast<U>(__builtin_bswap32(v));
  return static_cast<U>(__builtin_bswap64(v));
}

// One stored value as a double (little-endian, as PCL writes on every platform it runs on).
double load_value(const char* p, const Field& f) {
  const auto le = [p](auto v) {
    std::memcpy(&v, p, sizeof v);
    return from_little_endian(v);
  };
  if (f.type == 'F') {
    if (f.size == 4) return std::bit_cast<float>(le(std::uint32_t{}));
    return std::bit_cast<double>(le(std::uint64_t{}));
  }
  switch (f.size) {
    case 1:
      return f.type == 'I' ? static_cast<double>(static_cast<std::int8_t>(*p))
                           : static_cast<double>(static_cast<std::uint8_t>(*p));
    case 2:
      return f.type == 'I' ? static_cast<double>(static_cast<std::int16_t>(le(std::uint16_t{})))
                           : static_cast<double>(le(std::uint16_t{}));
    case 4:
      return f.type == 'I' ? static_cast<double>(static_cast<std::int32_t>(le(std::uint32_t{})))
                           : static_cast<double>(le(std::uint32_t{}));
    default:
      return f.type == 'I' ? static_cast<double>(static_cast<std::int64_t>(le(std::uint64_t{})))
                           : static_cast<double>(le(std::uint64_t{}));
  }
}

void read_ascii(const std::string& path, std::string_view bytes, const PcdHeader& h, Mesh& mesh) {
  // The header's lines come first: line numbers count from the file's start.
  TextCursor cur(path, bytes.substr(h.body), h.data_line + 1);
  mesh.vertices.reserve(std::min<std::uint64_t>(h.points, (bytes.size() - h.body) / 6));  // "0 0 0\n"
  for (std::uint64_t i = 0; i < h.points; ++i) {
    cur.skip_space();
    if (cur.at_end())
      cur.fail("file ends after " + std::to_string(i) + " of the header's " + std::to_string(h.points) +
               " points");
    double xyz[3] = {0, 0, 0};
    for (std::size_t f = 0; f < h.fields.size(); ++f)
      for (std::size_t c = 0; c < h.fields[f].count; ++c) {
        if (cur.at_eol())
          cur.fail("point " + std::to_string(i) + " ends before field '" + h.fields[f].name + "'");
        const double v = cur.number(h.fields[f].name.c_str());
        for (int a = 0; a < 3; ++a)
          if (static_cast<int>(f) == h.xyz[a]) xyz[a] = v;
      }
    if (!cur.at_eol()) cur.fail("extra values after point " + std::to_string(i) + "'s last field");
    mesh.vertices.emplace_back(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]),
                               static_cast<float>(xyz[2]));
    cur.next_line();
  }
  cur.skip_space();
  if (!cur.at_end()) cur.fail("text after the header's " + std::to_string(h.points) + " points");
}

// The point records' bytes: from the file (binary) or decompressed (binary_compressed).
// `field_major`: all points' first field, then all second, ... (the compressed layout).
void read_records(const std::string& path, std::string_view data, std::size_t at, const PcdHeader& h,
                  bool field_major, Mesh& mesh) {
  std::size_t stride = 0;
  std::array<std::size_t, 3> offset{}, step{};
  std::size_t before = 0;
  for (std::size_t f = 0; f < h.fields.size(); ++f) {
    for (int a = 0; a < 3; ++a)
      if (static_cast<int>(f) == h.xyz[a]) offset[a] = before;
    before += h.fields[f].size * h.fields[f].count;
  }
  stride = before;
  const std::uint64_t need = h.points * stride;
  // PCL pads a binary file to a whole memory page: bytes after the points are not read.
  if (data.size() < need || (field_major && data.size() != need))
    throw IngestError(path + ": byte " + std::to_string(at + std::min<std::uint64_t>(data.size(), need)) +
                      ": " + std::to_string(h.points) + " points of " + std::to_string(stride) +
                      " bytes need " + std::to_string(need) + " bytes, the " +
                      (field_major ? "decompressed data has " : "file has ") + std::to_string(data.size()));
  for (int a = 0; a < 3; ++a) {
    const Field& f = h.fields[static_cast<std::size_t>(h.xyz[a])];
    if (field_major) {
      offset[a] *= h.points;  // the field's block starts after the earlier fields' blocks
      step[a] = f.size;
    } else {
      step[a] = stride;
    }
  }
  const std::size_t n = static_cast<std::size_t>(h.points);
  mesh.vertices.resize(n);
  const Field& fx = h.fields[static_cast<std::size_t>(h.xyz[0])];
  const Field& fy = h.fields[static_cast<std::size_t>(h.xyz[1])];
  const Field& fz = h.fields[static_cast<std::size_t>(h.xyz[2])];
  const char* const base = data.data();
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < n; ++i)
    mesh.vertices[i] = Eigen::Vector3f(static_cast<float>(load_value(base + offset[0] + i * step[0], fx)),
                                       static_cast<float>(load_value(base + offset[1] + i * step[1], fy)),
                                       static_cast<float>(load_value(base + offset[2] + i * step[2], fz)));
}

void read_compressed(const std::string& path, std::string_view bytes, const PcdHeader& h, Mesh& mesh) {
  const std::size_t at = h.body;
  if (bytes.size() - at < 8)
    throw IngestError(path + ": byte " + std::to_string(at) +
                      ": file ends before binary_compressed's two sizes (8 bytes)");
  std::uint32_t packed = 0, unpacked = 0;
  std::memcpy(&packed, bytes.data() + at, 4);
  std::memcpy(&unpacked, bytes.data() + at + 4, 4);
  packed = from_little_endian(packed), unpacked = from_little_endian(unpacked);
  const std::size_t stream = at + 8;
  // (As binary, padded to a whole page: bytes after the compressed data are not read.)
  if (packed > bytes.size() - stream)
    throw IngestError(path + ": byte " + std::to_string(at) + ": compressed size " + std::to_string(packed) +
                      ", but only " + std::to_string(bytes.size() - stream) + " bytes follow");
  std::size_t stride = 0;
  for (const Field& f : h.fields) stride += f.size * f.count;
  if (unpacked != h.points * stride)
    throw IngestError(path + ": byte " + std::to_string(at + 4) + ": uncompressed size " +
                      std::to_string(unpacked) + ", but " + std::to_string(h.points) + " points of " +
                      std::to_string(stride) + " bytes are " + std::to_string(h.points * stride));
  // An LZF run of 3 bytes gives at most 264: a larger claim is not LZF (and is not
  // allocated).
  if (unpacked / 88 > packed + 1)
    throw IngestError(path + ": byte " + std::to_string(at + 4) + ": uncompressed size " +
                      std::to_string(unpacked) + " from " + std::to_string(packed) +
                      " compressed bytes is more than LZF can give");
  std::string data(unpacked, '\0');
  if (const auto error = lzf_decompress(bytes.substr(stream, packed), data))
    throw IngestError(path + ": byte " + std::to_string(stream + error->offset) +
                      ": bad LZF data: " + error->problem);
  read_records(path, data, stream, h, true, mesh);
}

}  // namespace

Mesh read_pcd(const std::string& path, std::string_view bytes) {
  const PcdHeader h = parse_header(path, bytes);
  Mesh mesh;
  switch (h.data) {
    case Data::kAscii:
      read_ascii(path, bytes, h, mesh);
      break;
    case Data::kBinary:
      read_records(path, bytes.substr(h.body), h.body, h, false, mesh);
      break;
    case Data::kCompressed:
      read_compressed(path, bytes, h, mesh);
      break;
  }
  if (mesh.vertices.empty())
    throw IngestError(path + ": line " + std::to_string(h.data_line) + ": no points in the PCD file");
  return mesh;
}

}  // namespace dentmark::ingest::detail
