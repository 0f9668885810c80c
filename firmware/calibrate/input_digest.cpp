#include "dentmark/firmware/calibrate/input_digest.h"

#include <openssl/evp.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <memory>

#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {

std::string inputs_sha256(const std::string& settings, const std::vector<std::filesystem::path>& files) {
  const std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), &EVP_MD_CTX_free);
  if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1)
    throw CalibrateError("SHA-256 unavailable (OpenSSL)");
  auto feed = [&](const void* p, std::size_t n) {
    if (EVP_DigestUpdate(ctx.get(), p, n) != 1) throw CalibrateError("SHA-256 failed (OpenSSL)");
  };
  feed(settings.data(), settings.size());
  std::array<char, 1 << 16> buf{};
  for (const auto& f : files) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(f, ec);
    std::ifstream in(f, std::ios::binary);
    if (ec || !in) throw CalibrateError(f.string() + ": cannot read");
    const std::string head = f.filename().string() + '\0' + std::to_string(size) + '\0';
    feed(head.data(), head.size());
    while (in) {
      in.read(buf.data(), buf.size());
      feed(buf.data(), static_cast<std::size_t>(in.gcount()));
    }
    if (in.bad()) throw CalibrateError(f.string() + ": cannot read");
  }
  std::array<unsigned char, EVP_MAX_MD_SIZE> d{};
  unsigned len = 0;
  if (EVP_DigestFinal_ex(ctx.get(), d.data(), &len) != 1) throw CalibrateError("SHA-256 failed (OpenSSL)");
  std::string hex;
  char b[3];
  for (unsigned i = 0; i < len; ++i) {
    std::snprintf(b, sizeof b, "%02x", d[i]);
    hex += b;
  }
  return hex;
}

}  // namespace dentmark::calibrate
