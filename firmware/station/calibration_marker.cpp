#include "dentmark/firmware/station/calibration_marker.h"

#include <fstream>

#include "dentmark/common/atomic_file.h"
#include "dentmark/firmware/station/station.h"

namespace dentmark::station {

std::optional<std::string> calibration_bad_reason(const std::filesystem::path& dir) {
  std::ifstream in(dir / kCalibrationBadFile);
  if (!in) return std::nullopt;
  std::string line;
  std::getline(in, line);
  return line;
}

void mark_calibration_bad(const std::filesystem::path& dir, const std::string& reason) {
  files::write_atomically(dir / kCalibrationBadFile, reason + "\n");
}

bool clear_calibration_bad(const std::filesystem::path& dir) {
  return std::filesystem::remove(dir / kCalibrationBadFile);
}

std::uint32_t calibration_faults(const std::filesystem::path& dir) {
  std::error_code ec;
  return std::filesystem::exists(dir / kCalibrationBadFile, ec) ? fault::kCalibration : 0u;
}

}  // namespace dentmark::station
