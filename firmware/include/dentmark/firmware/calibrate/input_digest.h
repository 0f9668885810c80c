#pragma once
// Provenance of a calibration file: SHA-256 (OpenSSL) over its inputs, so the file
// names exactly the images and settings it came from, and the time it was made.

#include <filesystem>
#include <string>
#include <vector>

#include "dentmark/common/utc_time.h"

namespace dentmark::calibrate {

// Lower-case hex SHA-256 over, in order: 'settings', then for each file its name
// (without folder), a NUL byte, its size as decimal text, a NUL byte and its bytes.
// Throws CalibrateError naming a file that cannot be read.
std::string inputs_sha256(const std::string& settings, const std::vector<std::filesystem::path>& files);

// The time it was made: the project's one UTC stamp.
using ::dentmark::utc_now_iso8601;

}  // namespace dentmark::calibrate
