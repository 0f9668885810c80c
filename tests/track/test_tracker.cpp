// End-to-end: rendered sequences through the tracker, errors against ground truth.
#include <gtest/gtest.h>

#include <cstdio>

#include "dentmark/firmware/track/replay.h"
#include "sequence_fixture.h"

namespace dentmark::track {
namespace {

using testing::TempDir;

MotionErrors run(const stereo::SequenceOptions& o, ReplayResult* out = nullptr, long from = -1, long to = -1,
                 TrackerOptions topt = {}) {
  TempDir tmp;
  const auto dir = tmp.path() / "seq";
  stereo::write_sequence(o, dir);
  const ReplayResult r = replay_sequence(dir, topt);
  const MotionErrors e = compare_with_truth(r, dir / "truth.csv", dir / "eval_points.csv", from, to);
  std::printf("frames %d failed %d mean %.3f mm rms %.3f mm worst %.3f mm\n", e.frames, e.failed,
              e.mean * 1e3, e.rms * 1e3, e.worst * 1e3);
  if (out) *out = r;
  return e;
}

TEST(Tracker, FollowsTheDoorWithSubMillimetreError) {
  ReplayResult r;
  const MotionErrors e = run(testing::small_sequence(6.0), &r);
  EXPECT_EQ(r.reference_features, 10);
  EXPECT_EQ(e.failed, 0);
  EXPECT_EQ(e.frames, 61);
  // Half resolution doubles the pixel footprint: twice the full-resolution targets.
  EXPECT_LT(e.mean, 1.0e-3);
  EXPECT_LT(e.worst, 3.0e-3);
}

}  // namespace
}  // namespace dentmark::track
