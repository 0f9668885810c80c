#pragma once
// Explicit little-endian field writer and bounds-checked reader. Floats travel as the
// bits of IEEE-754 binary64 (std::bit_cast), never as memcpy'd structs.

#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace dentmark::protocol::detail {

class ByteWriter {
 public:
  explicit ByteWriter(std::vector<std::uint8_t>& out) : out_(out) {}
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) { le(v, 2); }
  void u32(std::uint32_t v) { le(v, 4); }
  void u64(std::uint64_t v) { le(v, 8); }
  void f64(double v) { le(std::bit_cast<std::uint64_t>(v), 8); }
  void bytes(std::span<const std::uint8_t> b) { out_.insert(out_.end(), b.begin(), b.end()); }
  // u8 length + bytes; the caller has checked the length.
  void str8(const std::string& s) {
    u8(static_cast<std::uint8_t>(s.size()));
    out_.insert(out_.end(), s.begin(), s.end());
  }
  std::size_t size() const { return out_.size(); }
  // Overwrites a little-endian field written earlier (lengths known only afterwards).
  void patch_u16(std::size_t at, std::uint16_t v) {
    out_[at] = static_cast<std::uint8_t>(v);
    out_[at + 1] = static_cast<std::uint8_t>(v >> 8);
  }
  void patch_u32(std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) out_[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
  }

 private:
  void le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t>& out_;
};

// Reads little-endian fields from bytes[pos, end). Callers check remaining() first;
// the getters themselves never read past 'end'.
class ByteReader {
 public:
  ByteReader(std::span<const std::uint8_t> bytes, std::size_t pos, std::size_t end)
      : b_(bytes), pos_(pos), end_(end <= bytes.size() ? end : bytes.size()) {}
  std::size_t pos() const { return pos_; }
  std::size_t end() const { return end_; }
  std::size_t remaining() const { return pos_ < end_ ? end_ - pos_ : 0; }
  bool has(std::size_t n) const { return remaining() >= n; }
  void skip_to(std::size_t p) { pos_ = p < end_ ? p : end_; }

  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  double f64() { return std::bit_cast<double>(le(8)); }
  std::span<const std::uint8_t> take(std::size_t n) {
    if (!has(n)) n = remaining();
    auto s = b_.subspan(pos_, n);
    pos_ += n;
    return s;
  }

 private:
  std::uint64_t le(int n) {
    std::uint64_t v = 0;
    for (int i = 0; i < n && pos_ < end_; ++i, ++pos_) v |= std::uint64_t{b_[pos_]} << (8 * i);
    return v;
  }
  std::span<const std::uint8_t> b_;
  std::size_t pos_;
  std::size_t end_;
};

}  // namespace dentmark::protocol::detail
