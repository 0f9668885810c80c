#include "dentmark/common/protocol/hmac_key.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <sys/stat.h>

#include <cctype>
#include <fstream>
#include <sstream>

namespace dentmark::protocol {

HmacKey::HmacKey(std::vector<std::uint8_t> bytes) : bytes_(std::move(bytes)) {
  if (bytes_.size() < kMinBytes || bytes_.size() > kMaxBytes)
    throw std::invalid_argument("HMAC key of " + std::to_string(bytes_.size()) + " bytes; need " +
                                std::to_string(kMinBytes) + " to " + std::to_string(kMaxBytes));
}

HmacKey HmacKey::parse(const std::string& text, const std::string& source) {
  std::vector<std::uint8_t> bytes;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  int pending = -1;  // high nibble waiting for its low nibble
  int last_line = 0;
  while (std::getline(in, line)) {
    ++line_no;
    std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    for (std::size_t i = first; i < line.size(); ++i) {
      const unsigned char ch = static_cast<unsigned char>(line[i]);
      if (std::isspace(ch)) continue;
      if (!std::isxdigit(ch))
        throw KeyFileError(source + ":" + std::to_string(line_no) + ": column " + std::to_string(i + 1) +
                           ": not a hexadecimal digit");
      const int nibble = std::isdigit(ch) ? ch - '0' : std::tolower(ch) - 'a' + 10;
      if (pending < 0) {
        pending = nibble;
      } else {
        bytes.push_back(static_cast<std::uint8_t>(pending << 4 | nibble));
        pending = -1;
      }
      if (bytes.size() > kMaxBytes)
        throw KeyFileError(source + ":" + std::to_string(line_no) + ": key longer than " +
                           std::to_string(kMaxBytes) + " bytes");
    }
    last_line = line_no;
  }
  if (pending >= 0)
    throw KeyFileError(source + ":" + std::to_string(last_line) + ": odd number of hex digits");
  if (bytes.size() < kMinBytes)
    throw KeyFileError(source + ":" + std::to_string(last_line) + ": key of " + std::to_string(bytes.size()) +
                       " bytes; need at least " + std::to_string(kMinBytes));
  return HmacKey(std::move(bytes));
}

HmacKey HmacKey::load(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw KeyFileError(path + ": cannot open key file");
  if (!S_ISREG(st.st_mode) || st.st_size > 4096)
    throw KeyFileError(path + ": not a key file (regular, ≤ 4096 bytes)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw KeyFileError(path + ": cannot open key file");
  std::ostringstream os;
  os << in.rdbuf();
  return parse(os.str(), path);
}

std::array<std::uint8_t, 32> HmacKey::mac(std::span<const std::uint8_t> message) const {
  std::array<std::uint8_t, 32> out{};
  unsigned int len = 0;
  if (HMAC(EVP_sha256(), bytes_.data(), static_cast<int>(bytes_.size()), message.data(), message.size(),
           out.data(), &len) == nullptr ||
      len != out.size())
    throw std::runtime_error("HMAC-SHA-256 failed (OpenSSL)");
  return out;
}

bool HmacKey::verify(std::span<const std::uint8_t> message, std::span<const std::uint8_t> tag) const {
  if (tag.size() != 32) return false;
  const auto expected = mac(message);
  return CRYPTO_memcmp(expected.data(), tag.data(), expected.size()) == 0;
}

}  // namespace dentmark::protocol
