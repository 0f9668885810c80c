#pragma once
// LZF decompression (Marc Lehmann's liblzf format, as PCL's binary_compressed PCD uses
// it), checked against both buffers: hostile input ends in an error, never a read or
// write outside them.

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace dentmark::ingest::detail {

// The decompressed bytes must be exactly `out.size()` long. Returns nullopt on success,
// else what is wrong and the offset in `in` where it was found.
struct LzfError {
  std::size_t offset;
  std::string problem;
};
std::optional<LzfError> lzf_decompress(std::string_view in, std::string& out);

}  // namespace dentmark::ingest::detail
