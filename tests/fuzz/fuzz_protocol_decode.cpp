// libFuzzer target for the frame decoder: it must never crash, hang or read out of
// bounds (ASan/UBSan), and whatever it accepts must survive encode -> decode unchanged.
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "dentmark/common/protocol/codec.h"
#include "dentmark/common/protocol/hmac_key.h"

namespace pr = dentmark::protocol;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const pr::HmacKey key(std::vector<std::uint8_t>{0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10,
                                                         11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21,
                                                         22, 23, 24, 25, 26, 27, 28, 29, 30, 31});
  const std::span<const std::uint8_t> bytes(data, size);
  (void)pr::decode_header(bytes, {});
  pr::DecodeOptions with_key;
  with_key.key = &key;  // the golden key: signed seeds reach the payload decoder this way too
  const auto keyed = pr::decode(bytes, with_key);
  const auto r = pr::decode(bytes, {});
  if (keyed.ok() && !r.ok()) std::abort();  // a key only adds checks
  if (r.ok()) {
    if (r.value().header.frame_size() != size) std::abort();
    pr::EncodeOptions eo;
    eo.sequence = r.value().header.sequence;
    eo.send_time = r.value().header.send_time;
    const auto again = pr::encode(r.value().message, eo);  // must not throw: decode accepted it
    const auto back = pr::decode(again, {});
    if (!back.ok() || !(back.value().message == r.value().message)) std::abort();
    (void)pr::payload_digest(bytes);
  }
  return 0;
}
