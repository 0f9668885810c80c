#pragma once
// Where the daemon's files are when the command line does not say (docs/deploy.md):
// shared by `run` and `selftest`, which must look at the same folders.

#include <string>

namespace dentmark::edge {

inline constexpr const char* kDefaultCalibrationDir = "/etc/dentmark/calibration";

// systemd's $STATE_DIRECTORY (its first folder), else /var/lib/dentmark.
std::string default_state_dir();

}  // namespace dentmark::edge
