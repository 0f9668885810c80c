#pragma once
// One marking scenario of the station's twin, end to end: the edge daemon itself
// (daemon::EdgeDaemon, as `dentmark-edge run` wires it) with a simulation board
// (boards/sim/twin): simulated GPIO, cameras rendering the moving door with the robot's
// arm in view, and the robot simulator over Modbus TCP on loopback. The host's side
// sends the defect list over TCP with the same code as `dentmark send --wait`
// (protocol::JobSession) and collects the MarkReports; every spray is compared with
// where the defect truly was at that instant.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "dentmark/common/protocol/messages.h"
#include "dentmark/firmware/simulation/workcell.h"
#include "dentmark/sim/scan/sls_scan.h"

namespace dentmark::simulation {

using TruthDefect = sim::scan::TruthDefect;  // in sls

// What the scan's truth file says about the scanned door.
struct ScanTruth {
  std::vector<TruthDefect> defects;
  Transform T_sls_panel = Transform::Identity();
  double panel_width = 1.0, panel_height = 0.8;  // m
};

struct MarkError {
  std::uint32_t defect_id = 0;
  int truth_index = -1;        // matched truth defect (-1: the mark has no true defect)
  double t_spray = 0.0;        // s after the scan
  Eigen::Vector3d error_base;  // true tip − (true defect + standoff · normal), base axes, m
};

// The job the twin sends after the first one has ended (SimulationOptions::next_job):
// the same door scanned again where it then is, under the next job id.
struct NextJobResult {
  double t_scan = 0.0;            // s: when it was scanned and sent (time stood still meanwhile)
  protocol::MarkReport report;    // as the host received it, in the list's defect order
  std::vector<MarkError> errors;  // one per spray of this job matched to a true defect
  int defects_sent = 0;
  int marked = 0;
  bool valve_open_at_end = false;
  int valve_pulses = 0;  // valve openings from t_scan on
  int unmatched_marks = 0;
  Eigen::Vector3d mean_abs = Eigen::Vector3d::Zero();  // m
  Eigen::Vector3d max_abs = Eigen::Vector3d::Zero();
};

struct ScenarioResult {
  ScenarioOptions options;
  protocol::MarkReport report;    // as the host received it, in the list's defect order
  std::vector<MarkError> errors;  // one per spray matched to a true defect
  int defects_sent = 0;
  int marked = 0;
  bool valve_open_at_end = false;
  int valve_pulses = 0;     // times the sprayer valve line went active (simulated GPIO)
  int unmatched_marks = 0;  // sprays with no true defect within 10 mm (false detections)
  Eigen::Vector3d mean_abs = Eigen::Vector3d::Zero();  // mean |e_x|, |e_y|, |e_z|, m
  Eigen::Vector3d max_abs = Eigen::Vector3d::Zero();
  long frames_tracked = 0, frames_failed = 0;
  // The camera frames of the run (fps x its simulated time) when the tracker ran. Far
  // more than it took (tracked or failed): the machine could not keep up with the clock,
  // and the marks are not the station's.
  long frames_offered = 0;
  double sim_seconds = 0.0, real_seconds = 0.0;
  // The station's calibration against the truth (drawn or self-calibrated): translation
  // (m) and rotation (rad) errors of T_base_camL and T_camL_sls.
  bool self_calibrated = false;
  double robot_calibration_error = 0.0, robot_calibration_rotation = 0.0;
  double scanner_calibration_error = 0.0, scanner_calibration_rotation = 0.0;
  // With a fault: how long after it was injected (simulated seconds) the valve line was
  // low, the robot's tip stood still, and the last defect was reported. Negative: no
  // fault. The twin's clock charges no time to computation or to Modbus round trips,
  // so these are the station's reaction by design (poll periods, timeouts, the robot's
  // braking and watchdog), not this machine's speed.
  double fault_time = -1.0;
  double valve_closed_after = -1.0, robot_still_after = -1.0, reported_after = -1.0;
  // How long after the injection the station gave up on the panel (its first report of
  // a defect tracking_lost: the job runner's tracking check failed); negative when none.
  double detected_after = -1.0;
  // What the station was doing when the first fault came: spraying (valve line high),
  // moving (the tool's speed, m/s), or neither.
  bool valve_open_at_fault = false;
  double robot_speed_at_fault = 0.0;
  // The figures above (valve_pulses, errors, ...) are the first job's; with
  // SimulationOptions::next_job, the second job's are here.
  std::optional<NextJobResult> next_job;
};

// A fault the twin injects, `after` seconds after marking starts.
enum class FaultKind {
  kEstop,          // the e-stop line goes active
  kRobotLink,      // the robot stops answering Modbus for good
  kRobotLinkBlip,  // the robot drops one request (connection closed), then answers again
  kRobotFault,     // the robot reports its own fault (drive) and stops
  kCamera,         // the cameras stop delivering frames
  kTrackingLost,   // the panel leaves the cameras' view
  kDaemonKill,     // SIGKILL of the daemon, restarted after RestartSec (RestartableDaemon)
};
struct Fault {
  FaultKind kind = FaultKind::kEstop;
  double after = 0.0;  // s after marking starts
};
// "estop@2.5", "robot-link@1", "robot-blip@1", "robot-fault@3", "camera@2", "tracking@2",
// "daemon-kill@4".
// Throws std::invalid_argument naming what is wrong.
Fault parse_fault(const std::string& text);
const char* to_string(FaultKind kind);

struct SimulationOptions {
  bool arm_occludes = true;  // render the robot's arm in the cameras' view
  double lighting = 0.2;     // relative gain swing over 40 s
  // Use the true motion instead of the tracker (isolates tracking from the rest).
  bool truth_motion = false;
  // The target board's time to track one stereo frame, charged on the twin's clock
  // (CameraTrackingConfig::frame_processing_time): each estimate comes out this long
  // after the tracker took its frame up. 20 ms: 9 times the 2.2 ms one x86 core takes
  // for a 1280x1024 pair (docs/tracking.md), a Cortex-A53-class core's share.
  double frame_processing_time = 0.020;
  // Faults injected while the station marks (dentmark-edge simulate --fault KIND@T).
  std::vector<Fault> faults;
  std::string board_file;  // the twin's board (empty: boards/sim/twin/board.yaml of this source tree)
  // Commission the station with its own calibration commands on rendered views, cached
  // in this folder (self_calibration.h), instead of the scenario's drawn calibration
  // errors. Empty: drawn errors.
  std::string self_calibration_cache;
  // Serve an outside host (`dentmark send --wait`) on this port (0: any, logged)
  // instead of sending the list from inside. Time stands still until the list comes;
  // then the twin's clock jumps over the scan's age (send_time − scan_time) and the line
  // runs on: the list arrives after the panel has moved, as on a real line (the daemon
  // keeps 10 s of camera pairs to start from).
  bool serve = false;
  int serve_port = 0;
  double serve_timeout = 300.0;  // s (real) to wait for the host's list
  // After the first job has ended: every injected fault is cleared where it clears
  // (the e-stop released, the robot link restored, the robot's own fault reset at the
  // robot, the cameras back, the panel back in view) 0.5 s later; 1 s after that the
  // host scans the door again where it then is and sends it as the next job
  // (ScenarioResult::next_job). Not with serve.
  bool next_job = false;
};

// Runs one scenario. Throws std::runtime_error when the simulation itself cannot run
// (ports, tracker start); marking failures are in the result.
ScenarioResult run_scenario(const ScenarioOptions& scenario, const SimulationOptions& sim,
                            const protocol::DefectList& list, const ScanTruth& truth);

}  // namespace dentmark::simulation
