#pragma once
// The edge box's health check (docs/deploy.md, "Health check"): everything the daemon
// needs to start, opened and exercised once, each check reported on its own so that a
// failure names what is wrong. An updated root filesystem is marked good only when
// this passes; it runs before the daemon (it claims the same devices).
//
//   board file → link key → calibration (and its size against the board's cameras) →
//   GPIO lines claimable (valve driven inactive) → robot reachable and not faulted →
//   each camera opens and delivers a frame of the board's size → state folder writable.

#include <filesystem>
#include <string>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/hal/board_hal.h"

namespace dentmark::daemon {

struct SelfTestOptions {
  std::filesystem::path board_file;
  std::filesystem::path calibration_dir;
  std::filesystem::path state_dir;
  std::string key_file;         // empty: no key expected
  double camera_timeout = 5.0;  // s for each camera's first frame
  hal::HalChoice hal;
};

struct SelfTestCheck {
  std::string name;  // "board", "key", "calibration", "gpio", "robot", "camera left", ...
  bool passed = false;
  bool skipped = false;  // not run: a check it needs failed first
  std::string detail;    // what was found, or why it failed
};

struct SelfTestReport {
  std::vector<SelfTestCheck> checks;
  bool passed() const;
};

// Runs every check it can (a failed board file skips the device checks; the others go
// on after a failure). Never throws for a device or file problem: it is reported.
SelfTestReport run_self_test(const SelfTestOptions& options, clock::Clock& clock);

}  // namespace dentmark::daemon
