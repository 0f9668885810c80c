// `dentmark-edge selftest`: the box's health check (daemon/self_test.h). Prints one
// line per check and exits 0 only when every check passed; the update's mark-good
// step and an operator's first look after installation both run it.
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "commands.h"
#include "daemon_paths.h"
#include "dentmark/firmware/daemon/self_test.h"

namespace dentmark::edge {
namespace {

struct SelfTestArgs {
  std::string board_file;
  std::string calibration_dir = kDefaultCalibrationDir;
  std::string state_dir;
  std::string key_file;
  double camera_timeout = 5.0;
};

int run_self_test(const SelfTestArgs& args) {
  daemon::SelfTestOptions o;
  o.board_file = args.board_file;
  o.calibration_dir = args.calibration_dir;
  o.state_dir = args.state_dir.empty() ? default_state_dir() : args.state_dir;
  o.key_file = args.key_file;
  o.camera_timeout = args.camera_timeout;
  const daemon::SelfTestReport report = daemon::run_self_test(o, clock::monotonic_clock());
  for (const daemon::SelfTestCheck& c : report.checks) {
    const char* verdict = c.passed ? "ok  " : c.skipped ? "skip" : "FAIL";
    std::cout << verdict << " " << c.name << ": " << c.detail << "\n";
  }
  std::cout << (report.passed() ? "self-test passed" : "self-test FAILED") << std::endl;
  return report.passed() ? 0 : 1;
}

}  // namespace

void register_selftest(CLI::App& app) {
  auto args = std::make_shared<SelfTestArgs>();
  CLI::App* cmd = app.add_subcommand(
      "selftest",
      "Check the box can run: board file, key, calibration, GPIO lines, robot, both cameras, state folder "
      "(exit 0 only when all pass; run it while the daemon is stopped: it claims the same devices)");
  cmd->add_option("--board", args->board_file, "Board file")->required();
  cmd->add_option("--calibration", args->calibration_dir, "Calibration folder")->capture_default_str();
  cmd->add_option("--state-dir", args->state_dir,
                  "Job store (default: $STATE_DIRECTORY, else /var/lib/dentmark)");
  cmd->add_option("--key", args->key_file, "Link key file the daemon will use");
  cmd->add_option("--camera-timeout", args->camera_timeout, "s to wait for each camera's first frame")
      ->check(CLI::Range(0.1, 120.0))
      ->capture_default_str();
  cmd->callback([args] { exit_code() = run_self_test(*args); });
}

}  // namespace dentmark::edge
