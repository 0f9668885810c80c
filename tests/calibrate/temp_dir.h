#pragma once
// The calibration tests' temporary folders: the tests' shared helper.

#include "../support/temp_dir.h"

namespace dentmark::calibrate {
using ::dentmark::test::TempDir;
}  // namespace dentmark::calibrate
