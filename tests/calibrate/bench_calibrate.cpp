// Speed of `calibrate stereo` on the 13 opencv-doc VGA pairs (reading, corner
// detection, the fit, 10 leave-one-out refits, rectification): the target is
// ≤ 10 s on 2 cores. Run: bench_calibrate --benchmark_min_time=1
#include <benchmark/benchmark.h>

#include <opencv2/core/utility.hpp>

#include "dentmark/firmware/calibrate/stereo_from_images.h"
#include "opencv_sample_data.h"

namespace {

using namespace dentmark::calibrate;

void BM_CalibrateStereo13VgaPairs(benchmark::State& state) {
  const std::string problem = test::opencv_data_problem();
  if (!problem.empty()) {
    state.SkipWithError(problem.c_str());
    return;
  }
  cv::setNumThreads(static_cast<int>(state.range(0)));
  const TargetSpec t = parse_target("chessboard:9x6", 0.025, 0.0, "");
  for (auto _ : state) {
    const StereoCalibrationRun run = calibrate_stereo_images(test::kOpenCvData, t);
    benchmark::DoNotOptimize(run.fit.rms_px);
    state.counters["views_used"] = run.fit.views_used;
    state.counters["rms_px"] = run.fit.rms_px;
  }
}
BENCHMARK(BM_CalibrateStereo13VgaPairs)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
