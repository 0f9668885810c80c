// PLY (Turk 1994): ascii, binary_little_endian, binary_big_endian. Vertex x, y, z as
// any scalar type; faces as a list of indices (any integer count/index types); every
// other element and property is skipped.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "dentmark/common/ingest/detail/readers.h"
#include "text_cursor.h"

namespace dentmark::ingest::detail {
namespace {

enum class Scalar { kI8, kU8, kI16, kU16, kI32, kU32, kF32, kF64 };

std::optional<Scalar> scalar_from(std::string_view s) {
  if (s == "char" || s == "int8") return Scalar::kI8;
  if (s == "uchar" || s == "uint8") return Scalar::kU8;
  if (s == "short" || s == "int16") return Scalar::kI16;
  if (s == "ushort" || s == "uint16") return Scalar::kU16;
  if (s == "int" || s == "int32") return Scalar::kI32;
  if (s == "uint" || s == "uint32") return Scalar::kU32;
  if (s == "float" || s == "float32") return Scalar::kF32;
  if (s == "double" || s == "float64") return Scalar::kF64;
  return std::nullopt;
}

std::size_t scalar_size(Scalar s) {
  switch (s) {
    case Scalar::kI8:
    case Scalar::kU8:
      return 1;
    case Scalar::kI16:
    case Scalar::kU16:
      return 2;
    case Scalar::kI32:
    case Scalar::kU32:
    case Scalar::kF32:
      return 4;
    case Scalar::kF64:
      return 8;
  }
  return 1;
}

struct Property {
  std::string name;
  Scalar type = Scalar::kF32;
  bool is_list = false;
  Scalar count_type = Scalar::kU8;
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  std::size_t line = 0;  // of its 'element' statement in the header
};

enum class Encoding { kAscii, kLittle, kBig };

template <typename T>
T load(const char* p, bool swap) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if (swap) {
    if constexpr (sizeof(T) == 2) {
      std::uint16_t u;
      std::memcpy(&u, &v, 2);
      u = static_cast<std::uint16_t>((u >> 8) | (u << 8));
      std::memcpy(&v, &u, 2);
    } else if constexpr (sizeof(T) == 4) {
      std::uint32_t u;
      std::memcpy(&u, &v, 4);
      u = __builtin_bswap32(u);
      std::memcpy(&v, &u, 4);
    } else if constexpr (sizeof(T) == 8) {
      std::uint64_t u;
      std::memcpy(&u, &v, 8);
      u = __builtin_bswap64(u);
      std::memcpy(&v, &u, 8);
    }
  }
  return v;
}

double load_scalar(const char* p, Scalar s, bool swap) {
  switch (s) {
    case Scalar::kI8:
      return static_cast<std::int8_t>(*p);
    case Scalar::kU8:
      return static_cast<std::uint8_t>(*p);
    case Scalar::kI16:
      return load<std::int16_t>(p, swap);
    case Scalar::kU16:
      return load<std::uint16_t>(p, swap);
    case Scalar::kI32:
      return load<std::int32_t>(p, swap);
    case Scalar::kU32:
      return load<std::uint32_t>(p, swap);
    case Scalar::kF32:
      return load<float>(p, swap);
    case Scalar::kF64:
      return load<double>(p, swap);
  }
  return 0.0;
}

// An index or count as stored; any scalar type, but a value that is not a whole
// number in range (NaN, 1e30 in a float list) comes back as -1 and is rejected by the
// caller instead of being cast (which would be undefined behaviour).
std::int64_t load_index(const char* p, Scalar s, bool swap) {
  const double v = load_scalar(p, s, swap);
  if (!(v >= 0.0 && v < 9.0e15) || v != std::floor(v)) return -1;
  return static_cast<std::int64_t>(v);
}

// The usual 13-byte face record (uchar 3, three native 32-bit indices): true and the
// corners in v when it is a triangle with every index below nv. As unsigned, a negative
// int32 index is >= 2^31, so the range check rejects it as well.
inline bool triangle_record(const char* q, std::uint64_t nv, bool signed_index, std::uint32_t v[3]) {
  std::memcpy(v, q + 1, 3 * sizeof(std::uint32_t));
  return static_cast<std::uint8_t>(q[0]) == 3 && v[0] < nv && v[1] < nv && v[2] < nv &&
         !(signed_index && (v[0] | v[1] | v[2]) >= 0x80000000u);
}

// Adds a polygon as a fan; drops faces with < 3 corners or out-of-range indices fail.
// Indices are checked against the vertex count the header declares: a PLY's elements
// may come in any order, faces before vertices too.
class FaceSink {
 public:
  FaceSink(Mesh& mesh, const std::string& path, std::uint64_t vertices)
      : mesh_(mesh), path_(path), vertices_(vertices) {}
  void begin() { corners_.clear(); }
  void corner(std::int64_t index, const std::string& where) {
    if (index < 0 || static_cast<std::uint64_t>(index) >= vertices_)
      throw IngestError(path_ + ": " + where + ": vertex index " + std::to_string(index) + " out of range (" +
                        std::to_string(vertices_) + " vertices)");
    corners_.push_back(static_cast<std::uint32_t>(index));
  }
  void end() {
    if (corners_.size() < 3) {
      ++mesh_.dropped_faces;
      return;
    }
    for (std::size_t k = 1; k + 1 < corners_.size(); ++k)
      mesh_.triangles.push_back({corners_[0], corners_[k], corners_[k + 1]});
  }

 private:
  Mesh& mesh_;
  const std::string& path_;
  const std::uint64_t vertices_;
  std::vector<std::uint32_t> corners_;
};

struct PlyHeader {
  Encoding encoding = Encoding::kAscii;
  std::vector<Element> elements;
  std::size_t body = 0;   // byte offset of the first element
  std::size_t lines = 0;  // header lines
};

// Where the line 'end_header' ends (its '\n', or the end of the file): the word alone on
// its line, blanks and a '\r' around it allowed, not inside a comment ("comment ends at
// end_header"); npos if there is none.
std::size_t end_of_header(std::string_view bytes) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  for (std::size_t at = bytes.find("end_header"); at != std::string_view::npos;
       at = bytes.find("end_header", at + 1)) {
    std::size_t b = at;
    while (b > 0 && blank(bytes[b - 1])) --b;
    if (b > 0 && bytes[b - 1] != '\n') continue;
    std::size_t e = at + 10;
    while (e < bytes.size() && blank(bytes[e])) ++e;
    if (e == bytes.size() || bytes[e] == '\n') return e;
  }
  return std::string_view::npos;
}

PlyHeader parse_header(const std::string& path, std::string_view bytes) {
  const std::size_t header_end = end_of_header(bytes);
  if (bytes.substr(0, 3) != "ply" || header_end == std::string_view::npos)
    throw IngestError(path + ": line 1: not a PLY file (no 'ply' magic or no 'end_header' line)");
  if (header_end == bytes.size())
    throw IngestError(path + ": byte " + std::to_string(bytes.size()) +
                      ": header not terminated by a newline");
  const std::size_t body = header_end + 1;
  TextCursor hdr(path, bytes.substr(0, body));
  hdr.next_line();  // "ply"
  std::optional<Encoding> encoding;
  std::vector<Element> elements;
  while (!hdr.at_end()) {
    const std::string_view key = hdr.word();
    if (key == "format") {
      const std::string_view f = hdr.word();
      if (f == "ascii")
        encoding = Encoding::kAscii;
      else if (f == "binary_little_endian")
        encoding = Encoding::kLittle;
      else if (f == "binary_big_endian")
        encoding = Encoding::kBig;
      else
        hdr.fail("unknown format '" + std::string(f) + "'");
    } else if (key == "element") {
      Element e;
      e.line = hdr.line();
      e.name = std::string(hdr.word());
      const long long n = hdr.integer("element count");
      if (n < 0) hdr.fail("negative element count");
      // Faces index the one vertex list, wherever it comes: with a second, which they
      // point into would be a guess.
      if (e.name == "vertex" &&
          std::any_of(elements.begin(), elements.end(), [](const Element& o) { return o.name == "vertex"; }))
        hdr.fail("a second 'vertex' element");
      // Triangles hold 32-bit indices.
      if (e.name == "vertex" &&
          static_cast<unsigned long long>(n) > std::numeric_limits<std::uint32_t>::max())
        hdr.fail(std::to_string(n) + " vertices; at most 2^32 - 1 are supported");
      e.count = static_cast<std::uint64_t>(n);
      elements.push_back(std::move(e));
    } else if (key == "property") {
      if (elements.empty()) hdr.fail("property before any element");
      Property prop;
      const std::string_view t = hdr.word();
      if (t == "list") {
        prop.is_list = true;
        const auto ct = scalar_from(hdr.word());
        const auto it = scalar_from(hdr.word());
        if (!ct || !it) hdr.fail("unknown list property type");
        prop.count_type = *ct;
        prop.type = *it;
      } else {
        const auto st = scalar_from(t);
        if (!st) hdr.fail("unknown property type '" + std::string(t) + "'");
        prop.type = *st;
      }
      prop.name = std::string(hdr.word());
      elements.back().properties.push_back(prop);
    } else if (key == "end_header") {
      break;
    } else if (!(key.empty() || key == "comment" || key == "obj_info")) {
      hdr.fail("unknown header keyword '" + std::string(key) + "'");
    }
    hdr.next_line();
  }
  if (!encoding) throw IngestError(path + ": line 2: no 'format' line in the PLY header");
  for (const Element& e : elements) {
    if (e.name != "vertex") continue;
    for (const char* axis : {"x", "y", "z"})
      if (std::none_of(e.properties.begin(), e.properties.end(),
                       [&](const Property& p) { return !p.is_list && p.name == axis; }))
        throw IngestError(path + ": line " + std::to_string(e.line) + ": element 'vertex' has no property '" +
                          axis + "'");
  }
  return {*encoding, std::move(elements), body, hdr.line()};
}

// An ascii list count or index: an integer, or for a float type a whole number.
long long ascii_index(TextCursor& cur, Scalar type, const char* what) {
  if (type != Scalar::kF32 && type != Scalar::kF64) return cur.integer(what);
  const double v = cur.number(what);
  if (!(v > -9.0e15 && v < 9.0e15) || v != std::floor(v))
    cur.fail(std::string("expected a whole number for ") + what);
  return static_cast<long long>(v);
}

// --- The stages of read_ply: the header, then an ascii or a binary body ---

// One ascii element's records, a line each: a vertex's x, y, z (other values read and
// left), a face's corner list (vertex_indices or vertex_index) into 'faces', any other
// list's numbers read and left.
void read_ascii_element(TextCursor& cur, const Element& e, std::uint64_t can_hold, Mesh& mesh,
                        FaceSink& faces) {
  int ix = -1, iy = -1, iz = -1, ilist = -1;
  for (std::size_t k = 0; k < e.properties.size(); ++k) {
    const auto& n = e.properties[k].name;
    if (e.name == "vertex" && !e.properties[k].is_list) {
      if (n == "x") ix = static_cast<int>(k);
      if (n == "y") iy = static_cast<int>(k);
      if (n == "z") iz = static_cast<int>(k);
    }
    if (e.name == "face" && e.properties[k].is_list && (n == "vertex_indices" || n == "vertex_index"))
      ilist = static_cast<int>(k);
  }
  if (e.name == "vertex") mesh.vertices.reserve(std::min(e.count, can_hold));
  if (e.name == "face") mesh.triangles.reserve(std::min(e.count, can_hold));
  for (std::uint64_t r = 0; r < e.count; ++r) {
    cur.skip_space();
    if (cur.at_end())
      cur.fail("file ends inside element '" + e.name + "' (" + std::to_string(r) + " of " +
               std::to_string(e.count) + " read)");
    double xyz[3] = {0, 0, 0};
    for (std::size_t k = 0; k < e.properties.size(); ++k) {
      const Property& p = e.properties[k];
      if (p.is_list) {
        const long long n = ascii_index(cur, p.count_type, "list count");
        if (n < 0 || n > 1'000'000) cur.fail("bad list count " + std::to_string(n));
        const bool take = static_cast<int>(k) == ilist;
        if (take) {
          faces.begin();
          for (long long j = 0; j < n; ++j)
            faces.corner(ascii_index(cur, p.type, "vertex index"), "line " + std::to_string(cur.line()));
          faces.end();
        } else {  // any other list (MeshLab's 'list uchar float texcoord'): numbers of its type
          for (long long j = 0; j < n; ++j) cur.number(p.name.c_str());
        }
      } else {
        const double v = cur.number(p.name.c_str());
        if (static_cast<int>(k) == ix) xyz[0] = v;
        if (static_cast<int>(k) == iy) xyz[1] = v;
        if (static_cast<int>(k) == iz) xyz[2] = v;
      }
    }
    if (!cur.at_eol()) cur.fail("extra values at the end of a '" + e.name + "' line");
    if (e.name == "vertex")
      mesh.vertices.emplace_back(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]),
                                 static_cast<float>(xyz[2]));
    cur.next_line();
  }
}

// An ascii body: every element in the header's order, and nothing after the last one.
void read_ascii_body(const std::string& path, std::string_view bytes, const PlyHeader& header, Mesh& mesh,
                     FaceSink& faces) {
  TextCursor cur(path, bytes.substr(header.body), header.lines + 1);
  // A record takes at least two bytes ("0\n"): a header that claims more than the file
  // can hold is reported where the file ends, not by a failed allocation.
  const std::uint64_t can_hold = (bytes.size() - header.body) / 2;
  for (const Element& e : header.elements) read_ascii_element(cur, e, can_hold, mesh, faces);
  cur.skip_space();
  if (!cur.at_end())
    cur.fail("text after the last element" +
             (header.elements.empty() ? std::string() : " '" + header.elements.back().name + "'") +
             ": the header's element counts do not match the body");
}

// A binary body being read: the bytes, where the next element starts, and their order.
struct BinaryBody {
  const std::string& path;
  const char* base;
  std::size_t size;
  std::size_t off;
  bool swap;  // the file's byte order is not this machine's
  // Fails naming the byte when fewer than n bytes are left for 'what'.
  void need(std::size_t n, const std::string& what) const {
    if (n > size - off)
      throw IngestError(path + ": byte " + std::to_string(off) + ": file ends inside " + what);
  }
};

// The vertex element (fixed size, 'stride' bytes a record): x, y and z of any scalar
// type, side by side; float x, y, z in this machine's order with plain loads.
void read_binary_vertices(BinaryBody& b, const Element& e, std::size_t stride, Mesh& mesh) {
  std::size_t ox = SIZE_MAX, oy = SIZE_MAX, oz = SIZE_MAX, o = 0;
  Scalar tx = Scalar::kF32, ty = tx, tz = tx;
  for (const auto& p : e.properties) {
    if (p.name == "x") ox = o, tx = p.type;
    if (p.name == "y") oy = o, ty = p.type;
    if (p.name == "z") oz = o, tz = p.type;
    o += scalar_size(p.type);
  }
  const std::size_t size = b.size, off = b.off;
  if (stride != 0 && e.count > (size - off) / stride)
    throw IngestError(b.path + ": byte " + std::to_string(off + (size - off) / stride * stride) +
                      ": file ends inside vertex " + std::to_string((size - off) / stride) + " of " +
                      std::to_string(e.count));
  const std::size_t n = static_cast<std::size_t>(e.count);
  mesh.vertices.resize(n);
  const char* src = b.base + off;
  const bool swap = b.swap;
  const bool fast = !swap && tx == Scalar::kF32 && ty == Scalar::kF32 && tz == Scalar::kF32;
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < n; ++i) {
    const char* r = src + i * stride;
    if (fast) {
      float v[3];
      std::memcpy(&v[0], r + ox, 4);
      std::memcpy(&v[1], r + oy, 4);
      std::memcpy(&v[2], r + oz, 4);
      mesh.vertices[i] = Eigen::Vector3f(v[0], v[1], v[2]);
    } else {
      mesh.vertices[i] = Eigen::Vector3f(static_cast<float>(load_scalar(r + ox, tx, swap)),
                                         static_cast<float>(load_scalar(r + oy, ty, swap)),
                                         static_cast<float>(load_scalar(r + oz, tz, swap)));
    }
  }
  b.off += n * stride;
}

// The typical scanner's face block, the file's last element: a single list of exactly 3
// corners a face (count type ct, index type it), 'rec' bytes a face, filling what is left
// of the file. Checked and decoded side by side; true when every record is a valid
// triangle, else the mesh's triangles are left empty for the general path.
bool read_triangle_block(BinaryBody& b, const Element& e, Scalar ct, Scalar it, std::uint64_t nv,
                         Mesh& mesh) {
  const std::size_t cs = scalar_size(ct), is = scalar_size(it), rec = cs + 3 * is;
  const bool swap = b.swap;
  const char* src = b.base + b.off;
  const auto count = static_cast<std::int64_t>(e.count);
  std::int64_t bad = count;  // first record that is not a valid triangle
  mesh.triangles.resize(static_cast<std::size_t>(count));
  // The usual scanner layout (uchar count, 32-bit indices, native byte order) is
  // read with plain loads; anything else through the typed loader.
  const bool native32 = !swap && ct == Scalar::kU8 && (it == Scalar::kI32 || it == Scalar::kU32);
  if (native32) {
#pragma omp parallel for schedule(static) reduction(min : bad)
    for (std::int64_t r = 0; r < count; ++r) {
      std::uint32_t v[3];
      if (!triangle_record(src + r * static_cast<std::int64_t>(rec), nv, it == Scalar::kI32, v)) {
        bad = std::min(bad, r);
        continue;
      }
      mesh.triangles[static_cast<std::size_t>(r)] = {v[0], v[1], v[2]};
    }
  } else {
#pragma omp parallel for schedule(static) reduction(min : bad)
    for (std::int64_t r = 0; r < count; ++r) {
      const char* q = src + r * static_cast<std::int64_t>(rec);
      const std::int64_t a = load_index(q + cs, it, swap), b1 = load_index(q + cs + is, it, swap),
                         c = load_index(q + cs + 2 * is, it, swap);
      if (load_index(q, ct, swap) != 3 || a < 0 || b1 < 0 || c < 0 || static_cast<std::uint64_t>(a) >= nv ||
          static_cast<std::uint64_t>(b1) >= nv || static_cast<std::uint64_t>(c) >= nv) {
        bad = std::min(bad, r);
        continue;
      }
      mesh.triangles[static_cast<std::size_t>(r)] = {
          static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b1), static_cast<std::uint32_t>(c)};
    }
  }
  if (bad == count) {
    b.off = b.size;
    return true;
  }
  mesh.triangles.clear();  // not the simple layout after all: take the general path
  return false;
}

// An element with list properties, record by record: a face's corner list (vertex_indices
// or vertex_index) into 'faces', everything else stepped over. 'simple' (a face element of
// one list): a triangle is taken in one step, anything else property by property.
void read_binary_list_element(BinaryBody& b, const Element& e, bool simple, std::uint64_t nv, Mesh& mesh,
                              FaceSink& faces) {
  const bool is_face = e.name == "face";
  const Scalar ct = e.properties[0].count_type, it = e.properties[0].type;
  const std::size_t cs = scalar_size(ct), is = scalar_size(it);
  const char* const base = b.base;
  const std::size_t size = b.size;
  std::size_t& off = b.off;
  const bool swap = b.swap;
  for (std::uint64_t r = 0; r < e.count; ++r) {
    if (simple) {
      if (cs > size - off) b.need(cs, "face " + std::to_string(r));
      const std::int64_t n = load_index(base + off, ct, swap);
      if (n == 3 && 3 * is + cs <= size - off) {
        const char* q = base + off + cs;
        const std::int64_t a = load_index(q, it, swap), b1 = load_index(q + is, it, swap),
                           c = load_index(q + 2 * is, it, swap);
        if (a >= 0 && b1 >= 0 && c >= 0 && static_cast<std::uint64_t>(a) < nv &&
            static_cast<std::uint64_t>(b1) < nv && static_cast<std::uint64_t>(c) < nv) {
          mesh.triangles.push_back(
              {static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b1), static_cast<std::uint32_t>(c)});
          off += cs + 3 * is;
          continue;
        }
      }
    }
    // General path: walk each property.
    for (const Property& p : e.properties) {
      if (!p.is_list) {
        b.need(scalar_size(p.type), "element '" + e.name + "' " + std::to_string(r));
        off += scalar_size(p.type);
        continue;
      }
      const std::size_t at = off;
      b.need(scalar_size(p.count_type), "element '" + e.name + "' " + std::to_string(r));
      const std::int64_t n = load_index(base + off, p.count_type, swap);
      if (n < 0 || n > 1'000'000)
        throw IngestError(b.path + ": byte " + std::to_string(at) + ": bad list count " + std::to_string(n));
      off += scalar_size(p.count_type);
      b.need(static_cast<std::size_t>(n) * scalar_size(p.type),
             "element '" + e.name + "' " + std::to_string(r));
      const bool take = is_face && (p.name == "vertex_indices" || p.name == "vertex_index");
      // No writer stores a face without corners; a zero count is what the bytes of an
      // index (high bytes 0) give when the body is read out of step with the header.
      if (take && n == 0)
        throw IngestError(b.path + ": byte " + std::to_string(at) + ": face " + std::to_string(r) +
                          " has no corners: the header's element counts do not match the body");
      if (take) faces.begin();
      for (std::int64_t j = 0; j < n; ++j) {
        if (take) faces.corner(load_index(base + off, p.type, swap), "byte " + std::to_string(off));
        off += scalar_size(p.type);
      }
      if (take) faces.end();
    }
  }
}

// A binary body: each element by its layout (the vertices; other fixed-size elements
// skipped in one step; the face block; any element with lists), and nothing after the
// last one.
void read_binary_body(const std::string& path, std::string_view bytes, const PlyHeader& header,
                      std::uint64_t vertex_count, Mesh& mesh, FaceSink& faces) {
  const std::vector<Element>& elements = header.elements;
  const bool swap = (header.encoding == Encoding::kBig) != (std::endian::native == std::endian::big);
  BinaryBody b{path, bytes.data(), bytes.size(), header.body, swap};
  const std::size_t size = b.size;
  for (const Element& e : elements) {
    bool fixed = true;
    std::size_t stride = 0;
    for (const auto& p : e.properties) {
      if (p.is_list)
        fixed = false;
      else
        stride += scalar_size(p.type);
    }
    if (e.name == "vertex") {
      if (!fixed)
        throw IngestError(path + ": line " + std::to_string(e.line) +
                          ": a binary 'vertex' element with list properties is not supported");
      read_binary_vertices(b, e, stride, mesh);
      continue;
    }
    if (fixed) {  // skip a fixed-size element in one step
      if (stride != 0 && e.count > (size - b.off) / stride)
        throw IngestError(path + ": byte " + std::to_string(size) + ": file ends inside element '" + e.name +
                          "'");
      b.off += static_cast<std::size_t>(e.count) * stride;
      continue;
    }
    const bool is_face = e.name == "face";
    if (is_face)
      mesh.triangles.reserve(std::min<std::uint64_t>(e.count, size - b.off));  // a record: >= 1 byte
    // Common layout first: a single list property of uchar/int counts with 3 corners.
    const bool simple = is_face && e.properties.size() == 1 && e.properties[0].is_list;
    const Scalar ct = e.properties[0].count_type, it = e.properties[0].type;
    const std::size_t rec = scalar_size(ct) + 3 * scalar_size(it);
    if (simple && &e == &elements.back() && e.count > 0 && (size - b.off) / rec == e.count &&
        (size - b.off) % rec == 0 && read_triangle_block(b, e, ct, it, vertex_count, mesh))
      continue;
    read_binary_list_element(b, e, simple, vertex_count, mesh, faces);
  }
  // The body must end where the declared elements end: more bytes mean the counts are
  // wrong (too few faces declared, a vertex too many, ...), and the mesh read is not the
  // file's.
  if (b.off != size)
    throw IngestError(path + ": byte " + std::to_string(b.off) + ": " + std::to_string(size - b.off) +
                      " bytes after the last element" +
                      (elements.empty() ? std::string() : " '" + elements.back().name + "'") +
                      ": the header's element counts do not match the body");
}

}  // namespace

Mesh read_ply(const std::string& path, std::string_view bytes) {
  const PlyHeader header = parse_header(path, bytes);
  Mesh mesh;
  // The vertex count the header declares (the body is checked to hold them all).
  std::uint64_t vertex_count = 0;
  for (const Element& e : header.elements)
    if (e.name == "vertex") {
      vertex_count = e.count;
      break;
    }
  FaceSink faces(mesh, path, vertex_count);
  if (header.encoding == Encoding::kAscii)
    read_ascii_body(path, bytes, header, mesh, faces);
  else
    read_binary_body(path, bytes, header, vertex_count, mesh, faces);
  return mesh;
}

namespace {

// Where a binary little-endian PLY's blocks lie, when the file can be used in place:
// fixed-size elements, float x, y, z side by side in the vertices, and one trailing face
// list of uint8 counts and 32-bit indices.
struct InPlaceLayout {
  std::size_t vertex_block = 0, vertex_stride = 0, xyz = 0, face_block = 0;
  std::uint64_t vertex_count = 0, face_count = 0;
  bool signed_index = false;
};

// The layout, or nullopt when anything is left to read_ply.
std::optional<InPlaceLayout> in_place_layout(const PlyHeader& header, std::string_view bytes) {
  InPlaceLayout l;
  std::size_t off = header.body;
  bool has_vertices = false;
  for (const Element& e : header.elements) {
    const bool last = &e == &header.elements.back();
    if (e.name == "face" && last && e.properties.size() == 1 && e.properties[0].is_list) {
      const Property& p = e.properties[0];
      if (p.count_type != Scalar::kU8 || (p.type != Scalar::kI32 && p.type != Scalar::kU32))
        return std::nullopt;
      if (off > bytes.size() || (bytes.size() - off) / 13 != e.count || (bytes.size() - off) % 13 != 0)
        return std::nullopt;
      l.face_block = off, l.face_count = e.count, l.signed_index = p.type == Scalar::kI32;
      off = bytes.size();
      continue;
    }
    std::size_t stride = 0, ox = SIZE_MAX, oy = SIZE_MAX, oz = SIZE_MAX;
    for (const Property& p : e.properties) {
      if (p.is_list) return std::nullopt;
      if (e.name == "vertex" && p.type == Scalar::kF32) {
        if (p.name == "x") ox = stride;
        if (p.name == "y") oy = stride;
        if (p.name == "z") oz = stride;
      }
      stride += scalar_size(p.type);
    }
    if (stride != 0 && e.count > (bytes.size() - std::min(off, bytes.size())) / stride) return std::nullopt;
    if (e.name == "vertex") {
      if (ox == SIZE_MAX || oy != ox + 4 || oz != ox + 8) return std::nullopt;
      has_vertices = true, l.vertex_block = off, l.vertex_stride = stride, l.xyz = ox,
      l.vertex_count = e.count;
    }
    off += static_cast<std::size_t>(e.count) * stride;
  }
  if (!has_vertices || l.face_count == 0 || l.vertex_count >= (1ull << 32) - 1) return std::nullopt;
  return l;
}

// Every face a triangle with indices in range: as triangle_record for every face, as one
// branch-free reduction (the largest index, as unsigned: a negative int32 is >= 2^31; and
// any count byte but 3).
bool all_triangles_in_range(const char* faces, const InPlaceLayout& l) {
  const auto nf = static_cast<std::int64_t>(l.face_count);
  const std::uint64_t limit =
      l.signed_index ? std::min<std::uint64_t>(l.vertex_count, 0x80000000u) : l.vertex_count;
  std::uint32_t largest = 0, not_three = 0;
// (Chunks to whichever thread is free: on a shared machine one thread may run at half the
// other's speed. The reductions do not depend on the order.)
#pragma omp parallel for schedule(dynamic, 65536) reduction(max : largest) reduction(| : not_three)
  for (std::int64_t r = 0; r < nf; ++r) {
    const char* q = faces + 13 * r;
    std::uint32_t v[3];
    std::memcpy(v, q + 1, sizeof v);
    largest = std::max(largest, std::max(v[0], std::max(v[1], v[2])));
    not_three |= static_cast<std::uint8_t>(q[0]) ^ 3u;
  }
  return not_three == 0 && largest < limit;
}

// Every coordinate finite, and on the way the bounding box (the octree needs it) and
// each block of vertices' box (VertexBlocks), scaled as vertex() scales (scale > 0 keeps
// min and max apart). False on a coordinate that is not finite.
bool vertex_bounds(const char* vertices, const InPlaceLayout& l, float scale, VertexBlocks& boxes,
                   Eigen::Vector3f& lo, Eigen::Vector3f& hi) {
  const auto nv = static_cast<std::int64_t>(l.vertex_count);
  constexpr auto kBlock = static_cast<std::int64_t>(VertexBlocks::kSize);
  const std::int64_t blocks = (nv + kBlock - 1) / kBlock;
  boxes.lo.resize(static_cast<std::size_t>(blocks));
  boxes.hi.resize(static_cast<std::size_t>(blocks));
  std::int64_t bad = 0;
  const float inf = std::numeric_limits<float>::infinity();
  float x0 = inf, y0 = inf, z0 = inf, x1 = -inf, y1 = -inf, z1 = -inf;
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : bad) reduction(min : x0, y0, z0) \
    reduction(max : x1, y1, z1)
  for (std::int64_t b = 0; b < blocks; ++b) {
    // (Named scalars, not arrays: so the loop vectorises as the whole-scan one did.)
    float lx = inf, ly = inf, lz = inf, hx = -inf, hy = -inf, hz = -inf;
    std::int64_t nonfinite = 0;
    const std::int64_t end = std::min(nv, (b + 1) * kBlock);
    for (std::int64_t i = b * kBlock; i < end; ++i) {
      float c[3];
      std::memcpy(c, vertices + static_cast<std::size_t>(i) * l.vertex_stride, sizeof c);
      nonfinite += !(std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]));
      lx = std::min(lx, c[0]), ly = std::min(ly, c[1]), lz = std::min(lz, c[2]);
      hx = std::max(hx, c[0]), hy = std::max(hy, c[1]), hz = std::max(hz, c[2]);
    }
    bad += nonfinite;
    x0 = std::min(x0, lx), y0 = std::min(y0, ly), z0 = std::min(z0, lz);
    x1 = std::max(x1, hx), y1 = std::max(y1, hy), z1 = std::max(z1, hz);
    boxes.lo[static_cast<std::size_t>(b)] = Eigen::Vector3f(lx, ly, lz) * scale;
    boxes.hi[static_cast<std::size_t>(b)] = Eigen::Vector3f(hx, hy, hz) * scale;
  }
  lo = Eigen::Vector3f(x0, y0, z0) * scale, hi = Eigen::Vector3f(x1, y1, z1) * scale;
  return bad == 0;
}

}  // namespace

std::optional<MeshView> ply_in_place(const std::string& path, std::string_view bytes, float scale) {
  if (bytes.substr(0, 3) != "ply") return std::nullopt;
  const PlyHeader header = parse_header(path, bytes);
  if (header.encoding != Encoding::kLittle || std::endian::native != std::endian::little) return std::nullopt;
  const std::optional<InPlaceLayout> layout = in_place_layout(header, bytes);
  if (!layout) return std::nullopt;
  // One parallel pass over each block. Anything else (polygons, bad indices, NaN) goes
  // through read_ply, which fans, drops or reports it.
  const char* const faces = bytes.data() + layout->face_block;
  const char* const vertices = bytes.data() + layout->vertex_block + layout->xyz;
  if (!all_triangles_in_range(faces, *layout)) return std::nullopt;
  auto boxes = std::make_shared<VertexBlocks>();
  Eigen::Vector3f lo, hi;
  if (!vertex_bounds(vertices, *layout, scale, *boxes, lo, hi)) return std::nullopt;
  MeshView view(reinterpret_cast<const std::byte*>(vertices), layout->vertex_count, layout->vertex_stride,
                reinterpret_cast<const std::byte*>(faces + 1), layout->face_count, 13, scale);
  view.set_bounds(lo, hi);
  view.set_vertex_blocks(std::move(boxes));
  return view;
}

}  // namespace dentmark::ingest::detail
