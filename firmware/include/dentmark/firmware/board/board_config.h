#pragma once
// A board file (boards/<vendor>/<board>/board.yaml) describes what differs per edge
// board: CPU flags, GPIO line names, camera backend and devices, Modbus endpoint,
// host link port and workspace limits. Parsed and validated here; the daemon's
// wiring picks the hal backends from it.

#include <Eigen/Core>
#include <stdexcept>
#include <string>

namespace dentmark::board {

// One problem in a board file, with where it is. what() is a single line:
//   "<file>:<line>: <key>: <problem>"
class BoardError : public std::runtime_error {
 public:
  BoardError(std::string file, int line, std::string key, std::string problem);
  const std::string& file() const { return file_; }
  int line() const { return line_; }  // 1-based; 0 when unknown
  const std::string& key() const { return key_; }

 private:
  std::string file_;
  int line_;
  std::string key_;
};

struct GpioLine {
  std::string name;  // line name as the kernel reports it (found by name, not number)
  bool active_low = false;
};

// chardev: the kernel's GPIO character device (libgpiod); sim: simulated lines (the twin).
enum class GpioBackend { kChardev, kSim };

struct GpioConfig {
  GpioBackend backend = GpioBackend::kChardev;
  std::string chip_label;  // optional: restricts the search to the chip with this label
  GpioLine sprayer_valve;  // output; safe value is inactive (valve closed)
  GpioLine estop;          // input; active means stop
  GpioLine part_present;   // input; name empty when the board has no part sensor
};

enum class CameraBackend { kV4l2, kLibcamera, kReplay, kSim };

struct CameraConfig {
  CameraBackend backend = CameraBackend::kSim;
  std::string left;   // device path, libcamera id, replay folder or sim name
  std::string right;  // may be empty for replay (one folder holds both)
  int width = 1280;
  int height = 1024;
  double max_skew = 0.002;  // s, largest left/right timestamp difference for a pair
};

enum class ModbusTransport { kTcp, kRtu };

struct ModbusConfig {
  ModbusTransport transport = ModbusTransport::kTcp;
  std::string host;    // TCP
  int port = 502;      // TCP
  std::string device;  // RTU serial device
  int baud = 115200;
  char parity = 'N';  // 'N', 'E' or 'O'
  int data_bits = 8;
  int stop_bits = 1;
  int unit_id = 1;
  double timeout = 0.2;           // s per request
  double heartbeat_period = 0.1;  // s
};

struct LinkConfig {
  int port = 7878;  // TCP port the edge listens on for defect lists
};

struct Limits {
  Eigen::Vector3d workspace_min = Eigen::Vector3d::Zero();  // m, in base
  Eigen::Vector3d workspace_max = Eigen::Vector3d::Zero();  // m, in base
  double max_speed = 0.25;                                  // m/s
  double max_acceleration = 1.0;                            // m/s²

  bool contains(const Eigen::Vector3d& p_base) const {
    return (p_base.array() >= workspace_min.array()).all() && (p_base.array() <= workspace_max.array()).all();
  }
};

// The station's calibration checks (docs/calibration.md).
struct CalibrationConfig {
  // `dentmark-edge calibrate verify`: the stored T_base_camL holds while the target's
  // re-measured points transfer into base within this RMS (m).
  double verify_tolerance = 0.002;
};

struct BoardConfig {
  std::string source;  // file it was read from
  std::string vendor;
  std::string name;
  std::string cpu_arch;
  std::string cpu_flags;
  GpioConfig gpio;
  CameraConfig camera;
  ModbusConfig modbus;
  LinkConfig link;
  Limits limits;
  CalibrationConfig calibration;  // optional section; defaults above
};

// Reads and validates a board file. Throws BoardError naming the file, line and key.
BoardConfig load_board_config(const std::string& path);

// Parses board YAML text; 'source' names it in errors.
BoardConfig parse_board_config(const std::string& yaml_text, const std::string& source);

const char* to_string(CameraBackend backend);
const char* to_string(ModbusTransport transport);

}  // namespace dentmark::board
