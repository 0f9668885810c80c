// Codec throughput: encode and decode DefectLists of 10 and 4096 defects (the limit),
// unsigned and HMAC-signed.
#include <benchmark/benchmark.h>

#include <random>

#include "dentmark/common/protocol/codec.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "test_support.h"

namespace pr = dentmark::protocol;

namespace {

pr::DefectList list_of(std::size_t n) {
  std::mt19937_64 rng(7);
  pr::DefectList l = pr::test::random_list(rng, 0);
  while (l.defects.size() < n) {
    auto more = pr::test::random_list(rng, 64);
    for (auto& d : more.defects) {
      if (l.defects.size() == n) break;
      d.id = static_cast<std::uint32_t>(l.defects.size());
      l.defects.push_back(d);
    }
  }
  return l;
}

const pr::HmacKey& key() {
  static const pr::HmacKey k = pr::test::key_of(0x42);
  return k;
}

void BM_Encode(benchmark::State& state) {
  const auto l = list_of(static_cast<std::size_t>(state.range(0)));
  pr::EncodeOptions o;
  o.send_time = 1.75e9;
  o.key = state.range(1) ? &key() : nullptr;
  std::size_t bytes = 0;
  for (auto _ : state) {
    auto f = pr::encode(l, o);
    bytes += f.size();
    benchmark::DoNotOptimize(f.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
}

void BM_Decode(benchmark::State& state) {
  pr::EncodeOptions o;
  o.send_time = 1.75e9;
  o.key = state.range(1) ? &key() : nullptr;
  const auto f = pr::encode(list_of(static_cast<std::size_t>(state.range(0))), o);
  pr::DecodeOptions d;
  d.key = o.key;
  for (auto _ : state) {
    auto r = pr::decode(f, d);
    if (!r.ok()) state.SkipWithError("decode failed");
    benchmark::DoNotOptimize(r);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * f.size()));
}

}  // namespace

BENCHMARK(BM_Encode)->ArgsProduct({{10, 4096}, {0, 1}});
BENCHMARK(BM_Decode)->ArgsProduct({{10, 4096}, {0, 1}});
