#pragma once
// Pre-shared key for HMAC-SHA-256 frame authentication (OpenSSL).
// Key file: the key as hexadecimal text (32 to 128 bytes, i.e. 64 to 256 hex digits);
// whitespace and lines starting with '#' are ignored.

#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace dentmark::protocol {

class KeyFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class HmacKey {
 public:
  static constexpr std::size_t kMinBytes = 32;
  static constexpr std::size_t kMaxBytes = 128;

  // Throws std::invalid_argument when the size is outside [kMinBytes, kMaxBytes].
  explicit HmacKey(std::vector<std::uint8_t> bytes);
  // Reads a key file; throws KeyFileError "<path>:<line>: <problem>".
  static HmacKey load(const std::string& path);
  // Parses key file text; 'source' names it in errors.
  static HmacKey parse(const std::string& text, const std::string& source);

  std::array<std::uint8_t, 32> mac(std::span<const std::uint8_t> message) const;
  // Constant-time comparison of mac(message) with 'tag'.
  bool verify(std::span<const std::uint8_t> message, std::span<const std::uint8_t> tag) const;

 private:
  std::vector<std::uint8_t> bytes_;
};

}  // namespace dentmark::protocol
