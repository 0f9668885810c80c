// The median of a robust sigma's sample (60 k) and of a door's leaf spreads (1 M), by
// nth_smallest and by std::nth_element (items/s = elements/s).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>
#include <vector>

#include "dentmark/common/nth_smallest.h"

namespace {

std::vector<double> noise_sample(std::size_t n) {
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 2e-5);
  std::vector<double> v(n);
  for (auto& x : v) x = static_cast<float>(noise(rng));  // the maps' values are floats
  return v;
}

void BM_NthSmallest(benchmark::State& state) {
  const std::vector<double> base = noise_sample(static_cast<std::size_t>(state.range(0)));
  std::vector<double> v;
  for (auto _ : state) {
    v = base;
    benchmark::DoNotOptimize(dentmark::nth_smallest(v, v.size() / 2));
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_NthSmallest)->Arg(60000)->Arg(1000000)->Unit(benchmark::kMicrosecond);

void BM_NthElement(benchmark::State& state) {
  const std::vector<double> base = noise_sample(static_cast<std::size_t>(state.range(0)));
  std::vector<double> v;
  for (auto _ : state) {
    v = base;
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    benchmark::DoNotOptimize(*mid);
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_NthElement)->Arg(60000)->Arg(1000000)->Unit(benchmark::kMicrosecond);

}  // namespace
