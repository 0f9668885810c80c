#pragma once
// Block maps (bmaptool's .bmap, format 1.x and 2.x): which blocks of an image hold data,
// with a checksum per range. dentmark flash reads the map to check the written target
// block by block after bmaptool has written it.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace dentmark::flash {

struct BmapRange {
  std::uint64_t first_block = 0;
  std::uint64_t last_block = 0;  // inclusive
  std::string checksum;          // hex, of the range's bytes (within the image size)
};

struct Bmap {
  std::uint64_t image_size = 0;  // bytes
  std::uint64_t block_size = 0;  // bytes
  std::string checksum_type;     // sha256, sha1 or md5 (OpenSSL digest names)
  std::vector<BmapRange> ranges;
  std::uint64_t mapped_bytes() const;
};

// Reads a .bmap file; throws FlashError naming the file and line of what is missing
// or malformed.
Bmap read_bmap(const std::filesystem::path& path);

// Reads each mapped range back from 'target' (bypassing the page cache where the
// kernel allows) and compares its checksum with the map's. Returns the bytes checked;
// throws FlashError naming the target and the first range that differs.
std::uint64_t verify_against_bmap(const std::filesystem::path& target, const Bmap& bmap);

// Hex SHA-256 of the first 'length' bytes of 'path'; throws FlashError naming it when
// it is shorter or unreadable.
std::string sha256_of_prefix(const std::filesystem::path& path, std::uint64_t length);

}  // namespace dentmark::flash
