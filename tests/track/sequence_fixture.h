#pragma once
// Renders small stereo sequences into temporary directories for the tracker tests.

#include <unistd.h>

#include <filesystem>
#include <string>

#include "../support/temp_dir.h"
#include "dentmark/sim/stereo/sequence_writer.h"

namespace dentmark::track::testing {

// A temporary directory removed when it goes out of scope (the tests' shared helper).
using TempDir = dentmark::test::TempDir;

// The station's geometry at half resolution (640 x 512, f = 870 px): the same angles
// as 1280 x 1024 at f = 1740 px, a quarter of the pixels, so tests stay fast.
inline sim::stereo::SequenceOptions small_sequence(double seconds, double fps = 10.0) {
  sim::stereo::SequenceOptions o;
  o.width = 640;
  o.height = 512;
  o.focal_px = 870.0;
  o.seconds = seconds;
  o.fps = fps;
  return o;
}

}  // namespace dentmark::track::testing
