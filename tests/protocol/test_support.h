#pragma once
// Helpers shared by the protocol tests: random messages and re-sealing mutated frames.

#include <cstdint>
#include <random>
#include <vector>

#include "dentmark/common/protocol/codec.h"
#include "dentmark/common/protocol/crc32c.h"
#include "dentmark/common/protocol/hmac_key.h"

namespace dentmark::protocol::test {

inline std::string random_string(std::mt19937_64& rng, std::size_t max_len) {
  std::uniform_int_distribution<std::size_t> len(0, max_len);
  std::uniform_int_distribution<int> ch(0x20, 0x7E);
  std::string s(len(rng), ' ');
  for (char& c : s) c = static_cast<char>(ch(rng));
  return s;
}

inline DefectList random_list(std::mt19937_64& rng, std::size_t max_defects) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> pos(0.0, 1.0);
  std::uniform_int_distribution<std::size_t> count(0, max_defects);
  DefectList l;
  l.job_id = rng();
  l.panel_id = random_string(rng, 40);
  l.scan_time = 1.7e9 + 1e6 * pos(rng);
  l.frame = "x" + random_string(rng, 10);
  const std::size_t n = count(rng);
  std::uint32_t id = static_cast<std::uint32_t>(rng());
  for (std::size_t i = 0; i < n; ++i) {
    Defect d;
    d.id = id++;  // unique (wraps harmlessly)
    d.defect_class = static_cast<DefectClass>(rng() % 5);
    d.position = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 2.0;
    Eigen::Vector3d nv(u(rng), u(rng), u(rng));
    if (nv.norm() < 1e-3) nv = Eigen::Vector3d::UnitZ();
    d.normal = nv.normalized();
    d.diameter = 0.05 * pos(rng);
    d.height = 0.002 * u(rng);
    d.area = 0.002 * pos(rng);
    d.score = pos(rng);
    l.defects.push_back(d);
  }
  return l;
}

// Recomputes the HMAC (when 'key') and the CRC of a frame after a test mutated it,
// so that the decoder's later checks are reached.
inline void reseal(std::vector<std::uint8_t>& f, const HmacKey* key = nullptr) {
  const std::size_t crc_at = f.size() - wire::kCrcSize;
  if (key) {
    const std::size_t mac_at = crc_at - wire::kHmacSize;
    const auto tag = key->mac(std::span<const std::uint8_t>(f).first(mac_at));
    std::copy(tag.begin(), tag.end(), f.begin() + static_cast<std::ptrdiff_t>(mac_at));
  }
  const std::uint32_t c = crc32c(std::span<const std::uint8_t>(f).first(crc_at));
  for (int i = 0; i < 4; ++i) f[crc_at + i] = static_cast<std::uint8_t>(c >> (8 * i));
}

inline void put_u16(std::vector<std::uint8_t>& f, std::size_t at, std::uint16_t v) {
  f[at] = static_cast<std::uint8_t>(v);
  f[at + 1] = static_cast<std::uint8_t>(v >> 8);
}
inline void put_u32(std::vector<std::uint8_t>& f, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) f[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

inline HmacKey key_of(std::uint8_t fill) {
  return HmacKey(std::vector<std::uint8_t>(32, fill));
}

}  // namespace dentmark::protocol::test
