#include "dentmark/host/flash/bmap.h"

#include <fcntl.h>
#include <openssl/evp.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <string_view>

#include "dentmark/host/flash/target_check.h"

namespace dentmark::flash {
namespace fs = std::filesystem;
namespace {

std::string_view trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

// The text between <tag...> and </tag> on one line, if the line has that element.
std::optional<std::string_view> element(std::string_view line, std::string_view tag) {
  const std::string open = "<" + std::string(tag);
  const auto o = line.find(open);
  if (o == std::string_view::npos) return std::nullopt;
  const char after = o + open.size() < line.size() ? line[o + open.size()] : '\0';
  if (after != '>' && after != ' ') return std::nullopt;
  const auto gt = line.find('>', o);
  const auto close = line.find("</" + std::string(tag) + ">", gt);
  if (gt == std::string_view::npos || close == std::string_view::npos) return std::nullopt;
  return trim(line.substr(gt + 1, close - gt - 1));
}

std::uint64_t to_number(std::string_view text, const std::string& where) {
  std::uint64_t v = 0;
  if (text.empty() || text.find_first_not_of("0123456789") != std::string_view::npos)
    throw FlashError(where + ": '" + std::string(text) + "' is not a whole number");
  for (char c : text) v = v * 10 + static_cast<std::uint64_t>(c - '0');
  return v;
}

struct FdCloser {
  int fd;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

struct MdCtxFree {
  void operator()(EVP_MD_CTX* c) const { EVP_MD_CTX_free(c); }
};

// Digest of 'length' bytes of 'fd' from 'offset'.
std::string digest_range(int fd, const fs::path& path, const EVP_MD* md, std::uint64_t offset,
                         std::uint64_t length) {
  std::unique_ptr<EVP_MD_CTX, MdCtxFree> ctx(EVP_MD_CTX_new());
  if (!ctx || EVP_DigestInit_ex(ctx.get(), md, nullptr) != 1)
    throw FlashError("checksum: OpenSSL digest setup failed");
  std::vector<unsigned char> buf(1 << 20);
  while (length > 0) {
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(length, buf.size()));
    const ssize_t got = ::pread(fd, buf.data(), want, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0)
      throw FlashError(path.string() + ": cannot read at byte " + std::to_string(offset) + ": " +
                       std::strerror(errno));
    if (got == 0)
      throw FlashError(path.string() + ": ends at byte " + std::to_string(offset) +
                       ", before the image's end");
    EVP_DigestUpdate(ctx.get(), buf.data(), static_cast<std::size_t>(got));
    offset += static_cast<std::uint64_t>(got);
    length -= static_cast<std::uint64_t>(got);
  }
  unsigned char out[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  EVP_DigestFinal_ex(ctx.get(), out, &n);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  for (unsigned i = 0; i < n; ++i) {
    hex += kHex[out[i] >> 4];
    hex += kHex[out[i] & 15];
  }
  return hex;
}

int open_for_verify(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw FlashError(path.string() + ": cannot open to verify: " + std::strerror(errno));
  // Written pages leave the cache, so that the reads below come from the medium.
  ::fdatasync(fd);
  ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  return fd;
}

}  // namespace

std::uint64_t Bmap::mapped_bytes() const {
  std::uint64_t total = 0;
  for (const auto& r : ranges)
    total += std::min((r.last_block + 1) * block_size, image_size) - r.first_block * block_size;
  return total;
}

Bmap read_bmap(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw FlashError(path.string() + ": cannot open the block map: " + std::strerror(errno));
  Bmap map;
  bool in_map = false;
  std::size_t line_no = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    const std::string where = path.string() + ": line " + std::to_string(line_no);
    if (auto v = element(line, "ImageSize")) map.image_size = to_number(*v, where);
    if (auto v = element(line, "BlockSize")) map.block_size = to_number(*v, where);
    if (auto v = element(line, "ChecksumType")) map.checksum_type = std::string(*v);
    if (line.find("<BlockMap>") != std::string::npos) in_map = true;
    if (line.find("</BlockMap>") != std::string::npos) in_map = false;
    if (!in_map) continue;
    const auto range = element(line, "Range");
    if (!range) continue;
    BmapRange r;
    const auto c = line.find("chksum=\"");
    if (c != std::string::npos) {
      const auto end = line.find('"', c + 8);
      if (end == std::string::npos) throw FlashError(where + ": unterminated chksum attribute");
      r.checksum = line.substr(c + 8, end - c - 8);
    }
    const auto dash = range->find('-');
    r.first_block = to_number(trim(range->substr(0, dash)), where);
    r.last_block =
        dash == std::string_view::npos ? r.first_block : to_number(trim(range->substr(dash + 1)), where);
    if (r.last_block < r.first_block)
      throw FlashError(where + ": range " + std::string(*range) + " ends before it starts");
    map.ranges.push_back(std::move(r));
  }
  if (map.image_size == 0) throw FlashError(path.string() + ": no <ImageSize>");
  if (map.block_size == 0) throw FlashError(path.string() + ": no <BlockSize>");
  // Format 1.x maps name no type: their checksums are SHA-1.
  if (map.checksum_type.empty()) map.checksum_type = "sha1";
  for (const auto& r : map.ranges) {
    if (r.first_block * map.block_size >= map.image_size)
      throw FlashError(path.string() + ": range " + std::to_string(r.first_block) + "-" +
                       std::to_string(r.last_block) + " lies beyond the image's " +
                       std::to_string(map.image_size) + " bytes");
    if (r.checksum.empty())
      throw FlashError(path.string() + ": range " + std::to_string(r.first_block) + "-" +
                       std::to_string(r.last_block) + " has no checksum to verify against");
  }
  return map;
}

std::uint64_t verify_against_bmap(const fs::path& target, const Bmap& bmap) {
  const EVP_MD* md = EVP_get_digestbyname(bmap.checksum_type.c_str());
  if (!md) throw FlashError("block map: unknown checksum type '" + bmap.checksum_type + "'");
  FdCloser fd{open_for_verify(target)};
  std::uint64_t checked = 0;
  for (const auto& r : bmap.ranges) {
    const std::uint64_t begin = r.first_block * bmap.block_size;
    const std::uint64_t end = std::min((r.last_block + 1) * bmap.block_size, bmap.image_size);
    const std::string got = digest_range(fd.fd, target, md, begin, end - begin);
    if (got != r.checksum)
      throw FlashError(target.string() + ": verification failed: blocks " + std::to_string(r.first_block) +
                       "-" + std::to_string(r.last_block) + " (bytes " + std::to_string(begin) + "-" +
                       std::to_string(end - 1) + ") read back with " + bmap.checksum_type + " " + got +
                       ", the map says " + r.checksum);
    checked += end - begin;
  }
  return checked;
}

std::string sha256_of_prefix(const fs::path& path, std::uint64_t length) {
  FdCloser fd{open_for_verify(path)};
  return digest_range(fd.fd, path, EVP_sha256(), 0, length);
}

}  // namespace dentmark::flash
