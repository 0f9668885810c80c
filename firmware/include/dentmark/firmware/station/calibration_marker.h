#pragma once
// The "calibration known bad" marker: a file `calibration.bad` in the calibration
// folder holding the reason (one line). `dentmark-edge calibrate verify` writes it when
// the stored robot calibration no longer holds; a successful `calibrate robot` or
// `calibrate verify` removes it. While it exists the daemon reports Status fault bit 5
// (fault::kCalibration) and refuses jobs (Station::receive). Written atomically, so a
// reader sees either no marker or a whole one.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace dentmark::station {

inline constexpr const char* kCalibrationBadFile = "calibration.bad";

// The reason recorded in the marker, or nullopt when there is none.
std::optional<std::string> calibration_bad_reason(const std::filesystem::path& calibration_dir);
// Writes the marker (atomically). Throws files::FileError.
void mark_calibration_bad(const std::filesystem::path& calibration_dir, const std::string& reason);
// Removes the marker; true when there was one. Throws std::filesystem::filesystem_error.
bool clear_calibration_bad(const std::filesystem::path& calibration_dir);
// fault::kCalibration while the marker exists, else 0 (for StationDevices::extra_faults).
std::uint32_t calibration_faults(const std::filesystem::path& calibration_dir);

}  // namespace dentmark::station
