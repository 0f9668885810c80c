#pragma once
// SHA-256 (OpenSSL) over a calibration's inputs, so a calibration file names exactly
// the images and settings it came from.

#include <filesystem>
#include <string>
#include <vector>

namespace dentmark::calibrate {

// Lower-case hex SHA-256 over, in order: 'settings', then for each file its name
// (without folder), a NUL byte, its size as decimal text, a NUL byte and its bytes.
// Throws CalibrateError naming a file that cannot be read.
std::string inputs_sha256(const std::string& settings, const std::vector<std::filesystem::path>& files);

}  // namespace dentmark::calibrate
