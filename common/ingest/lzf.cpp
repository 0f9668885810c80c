// LZF stream: a sequence of runs, each opened by a control byte c.
//   c < 32:  a literal run of c + 1 bytes follows.
//   c >= 32: a back reference. Length L = c >> 5 (7: plus the next byte), copy L + 2
//            bytes from ((c & 31) << 8 | next byte) + 1 bytes back in the output;
//            source and destination may overlap (a repeated pattern).
#include "lzf.h"

namespace dentmark::ingest::detail {

std::optional<LzfError> lzf_decompress(std::string_view in, std::string& out) {
  const auto* const ip0 = reinterpret_cast<const unsigned char*>(in.data());
  const std::size_t n_in = in.size(), n_out = out.size();
  std::size_t i = 0, o = 0;
  while (i < n_in) {
    const std::size_t at = i;
    const unsigned ctrl = ip0[i++];
    if (ctrl < 32) {
      const std::size_t len = ctrl + 1;
      if (len > n_in - i)
        return LzfError{at, "literal run of " + std::to_string(len) + " bytes past the input's end"};
      if (len > n_out - o) return LzfError{at, "literal run past the declared uncompressed size"};
      out.replace(o, len, in.data() + i, len);
      i += len, o += len;
      continue;
    }
    std::size_t len = ctrl >> 5;
    if (len == 7) {
      if (i >= n_in) return LzfError{at, "back reference cut off"};
      len += ip0[i++];
    }
    if (i >= n_in) return LzfError{at, "back reference cut off"};
    const std::size_t back = ((static_cast<std::size_t>(ctrl & 31) << 8) | ip0[i++]) + 1;
    len += 2;
    if (back > o) return LzfError{at, "back reference before the start of the output"};
    if (len > n_out - o) return LzfError{at, "back reference past the declared uncompressed size"};
    for (std::size_t k = 0; k < len; ++k, ++o) out[o] = out[o - back];  // may overlap: byte by byte
  }
  if (o != n_out)
    return LzfError{n_in, "decompressed to " + std::to_string(o) + " bytes, the header declares " +
                              std::to_string(n_out)};
  return std::nullopt;
}

}  // namespace dentmark::ingest::detail
