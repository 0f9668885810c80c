#include "dentmark/firmware/board/board_config.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

namespace dentmark::board {

BoardError::BoardError(std::string file, int line, std::string key, std::string problem)
    : std::runtime_error(file + ":" + std::to_string(line) + ": " + key + ": " + problem),
      file_(std::move(file)),
      line_(line),
      key_(std::move(key)) {}

namespace {

// A YAML mapping with its dotted key path, so every error names file, line and key.
class Section {
 public:
  Section(const YAML::Node& node, std::string path, const std::string& file, int parent_line)
      : node_(node), path_(std::move(path)), file_(file), line_(parent_line) {
    if (node_.IsDefined() && !node_.IsNull()) line_ = node_.Mark().line + 1;
    if (!node_.IsMap()) fail(path_, "expected a mapping");
  }

  // Rejects keys this schema does not know: a typo must not silently fall back to a default.
  void allow_only(std::initializer_list<const char*> keys) const {
    const std::set<std::string> allowed(keys.begin(), keys.end());
    for (const auto& kv : node_) {
      const auto key = kv.first.as<std::string>();
      if (!allowed.count(key)) fail_at(kv.first, join(key), "unknown key");
    }
  }

  Section section(const char* key) const { return Section(required(key), join(key), file_, line_); }
  bool has(const char* key) const { return static_cast<bool>(node_[key]); }

  std::string string(const char* key) const {
    const YAML::Node n = required(key);
    if (!n.IsScalar()) fail_at(n, join(key), "expected a string");
    const auto s = n.as<std::string>();
    if (s.empty()) fail_at(n, join(key), "must not be empty");
    return s;
  }

  std::string string_or(const char* key, const std::string& fallback) const {
    return has(key) ? string(key) : fallback;
  }

  bool boolean(const char* key, bool fallback) const {
    if (!has(key)) return fallback;
    const YAML::Node n = node_[key];
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      fail_at(n, join(key), "expected true or false, got '" + scalar_text(n) + "'");
    }
  }

  double number(const char* key, double lo, double hi) const {
    return number_node(required(key), join(key), lo, hi);
  }

  double number_or(const char* key, double fallback, double lo, double hi) const {
    return has(key) ? number(key, lo, hi) : fallback;
  }

  int integer(const char* key, int lo, int hi) const {
    const YAML::Node n = required(key);
    int v = 0;
    try {
      v = n.as<int>();
    } catch (const YAML::Exception&) {
      fail_at(n, join(key), "expected an integer, got '" + scalar_text(n) + "'");
    }
    if (v < lo || v > hi)
      fail_at(
          n, join(key),
          std::to_string(v) + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return v;
  }

  int integer_or(const char* key, int fallback, int lo, int hi) const {
    return has(key) ? integer(key, lo, hi) : fallback;
  }

  Eigen::Vector3d vector3(const char* key, double lo, double hi) const {
    const YAML::Node n = required(key);
    if (!n.IsSequence() || n.size() != 3) fail_at(n, join(key), "expected a list of 3 numbers [x, y, z]");
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v(i) = number_node(n[i], join(key) + "[" + std::to_string(i) + "]", lo, hi);
    return v;
  }

  [[noreturn]] void fail(const std::string& key, const std::string& problem) const {
    throw BoardError(file_, line_, key, problem);
  }
  [[noreturn]] void fail_at(const YAML::Node& n, const std::string& key, const std::string& problem) const {
    throw BoardError(file_, n.IsDefined() ? n.Mark().line + 1 : line_, key, problem);
  }
  const std::string& path() const { return path_; }
  int line() const { return line_; }

 private:
  YAML::Node required(const char* key) const {
    const YAML::Node n = node_[key];
    if (!n) fail(join(key), "missing required key");
    return n;
  }
  std::string join(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  static std::string scalar_text(const YAML::Node& n) { return n.IsScalar() ? n.Scalar() : "<not a scalar>"; }

  double number_node(const YAML::Node& n, const std::string& key, double lo, double hi) const {
    double v = 0.0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail_at(n, key, "expected a number, got '" + scalar_text(n) + "'");
    }
    if (!std::isfinite(v) || v < lo || v > hi) {
      std::ostringstream os;
      os << v << " is out of range [" << lo << ", " << hi << "]";
      fail_at(n, key, os.str());
    }
    return v;
  }

  YAML::Node node_;
  std::string path_;
  const std::string& file_;
  int line_;
};

GpioLine parse_line(const Section& s) {
  s.allow_only({"line", "active_low"});
  return GpioLine{s.string("line"), s.boolean("active_low", false)};
}

CameraBackend parse_backend(const Section& s) {
  const std::string b = s.string("backend");
  if (b == "v4l2") return CameraBackend::kV4l2;
  if (b == "libcamera") return CameraBackend::kLibcamera;
  if (b == "replay") return CameraBackend::kReplay;
  if (b == "sim") return CameraBackend::kSim;
  s.fail(s.path() + ".backend", "'" + b + "' is not one of v4l2, libcamera, replay, sim");
}

ModbusConfig parse_modbus(const Section& s) {
  s.allow_only({"transport", "host", "port", "device", "baud", "parity", "data_bits", "stop_bits", "unit_id",
                "timeout", "heartbeat_period"});
  ModbusConfig m;
  const std::string transport = s.string("transport");
  if (transport == "tcp") {
    m.transport = ModbusTransport::kTcp;
    m.host = s.string("host");
    m.port = s.integer("port", 1, 65535);
  } else if (transport == "rtu") {
    m.transport = ModbusTransport::kRtu;
    m.device = s.string("device");
    m.baud = s.integer("baud", 1200, 4000000);
    const std::string parity = s.string_or("parity", "N");
    if (parity != "N" && parity != "E" && parity != "O") s.fail(s.path() + ".parity", "must be N, E or O");
    m.parity = parity[0];
    m.data_bits = s.integer_or("data_bits", 8, 5, 8);
    m.stop_bits = s.integer_or("stop_bits", 1, 1, 2);
  } else {
    s.fail(s.path() + ".transport", "'" + transport + "' is not tcp or rtu");
  }
  m.unit_id = s.integer_or("unit_id", 1, 0, 247);
  m.timeout = s.number_or("timeout", 0.2, 0.001, 10.0);
  m.heartbeat_period = s.number_or("heartbeat_period", 0.1, 0.001, 10.0);
  return m;
}

BoardConfig parse_root(const YAML::Node& root, const std::string& source) {
  const Section top(root, "", source, 1);
  top.allow_only({"board", "cpu", "gpio", "camera", "modbus", "link", "limits", "calibration"});
  BoardConfig cfg;
  cfg.source = source;

  const Section board = top.section("board");
  board.allow_only({"vendor", "name"});
  cfg.vendor = board.string("vendor");
  cfg.name = board.string("name");

  const Section cpu = top.section("cpu");
  cpu.allow_only({"arch", "flags"});
  cfg.cpu_arch = cpu.string("arch");
  if (cfg.cpu_arch != "aarch64" && cfg.cpu_arch != "x86_64")
    cpu.fail("cpu.arch", "'" + cfg.cpu_arch + "' is not aarch64 or x86_64");
  cfg.cpu_flags = cpu.string_or("flags", "");

  const Section gpio = top.section("gpio");
  gpio.allow_only({"backend", "chip_label", "sprayer_valve", "estop", "part_present"});
  const std::string gpio_backend = gpio.string_or("backend", "chardev");
  if (gpio_backend != "chardev" && gpio_backend != "sim")
    gpio.fail("gpio.backend", "'" + gpio_backend + "' is not chardev or sim");
  cfg.gpio.backend = gpio_backend == "sim" ? GpioBackend::kSim : GpioBackend::kChardev;
  cfg.gpio.chip_label = gpio.string_or("chip_label", "");
  cfg.gpio.sprayer_valve = parse_line(gpio.section("sprayer_valve"));
  cfg.gpio.estop = parse_line(gpio.section("estop"));
  // Optional: without a part sensor a job marks as soon as it tracks the panel.
  if (gpio.has("part_present")) cfg.gpio.part_present = parse_line(gpio.section("part_present"));
  const std::string& valve = cfg.gpio.sprayer_valve.name;
  if (valve == cfg.gpio.estop.name || valve == cfg.gpio.part_present.name ||
      cfg.gpio.estop.name == cfg.gpio.part_present.name)
    gpio.fail("gpio", "sprayer_valve, estop and part_present must be different lines");

  const Section cam = top.section("camera");
  cam.allow_only({"backend", "left", "right", "width", "height", "max_skew"});
  cfg.camera.backend = parse_backend(cam);
  cfg.camera.left = cam.string("left");
  cfg.camera.right =
      cfg.camera.backend == CameraBackend::kReplay ? cam.string_or("right", "") : cam.string("right");
  cfg.camera.width = cam.integer_or("width", 1280, 16, 16384);
  cfg.camera.height = cam.integer_or("height", 1024, 16, 16384);
  cfg.camera.max_skew = cam.number_or("max_skew", 0.002, 0.0, 1.0);

  cfg.modbus = parse_modbus(top.section("modbus"));

  if (top.has("link")) {
    const Section link = top.section("link");
    link.allow_only({"port"});
    cfg.link.port = link.integer_or("port", 7878, 1, 65535);
  }

  const Section lim = top.section("limits");
  lim.allow_only({"workspace_min", "workspace_max", "max_speed", "max_acceleration"});
  cfg.limits.workspace_min = lim.vector3("workspace_min", -10.0, 10.0);
  cfg.limits.workspace_max = lim.vector3("workspace_max", -10.0, 10.0);
  for (int i = 0; i < 3; ++i)
    if (!(cfg.limits.workspace_min(i) < cfg.limits.workspace_max(i)))
      lim.fail("limits.workspace_min", "must be below limits.workspace_max on every axis");
  cfg.limits.max_speed = lim.number("max_speed", 1e-4, 5.0);
  cfg.limits.max_acceleration = lim.number("max_acceleration", 1e-4, 50.0);

  if (top.has("calibration")) {
    const Section cal = top.section("calibration");
    cal.allow_only({"verify_tolerance"});
    // 0.1 mm is below what the stereo pair resolves at the working distance; 20 mm
    // would let a knocked camera pass.
    cfg.calibration.verify_tolerance = cal.number_or("verify_tolerance", 0.002, 1e-4, 0.02);
  }
  return cfg;
}

}  // namespace

BoardConfig parse_board_config(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw BoardError(source, e.mark.line + 1, "(syntax)", e.msg);
  }
  if (!root || root.IsNull()) throw BoardError(source, 1, "(root)", "file is empty");
  return parse_root(root, source);
}

BoardConfig load_board_config(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw BoardError(path, 0, "(file)", "cannot open for reading");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw BoardError(path, 0, "(file)", "read error");
  return parse_board_config(text.str(), path);
}

const char* to_string(CameraBackend backend) {
  switch (backend) {
    case CameraBackend::kV4l2:
      return "v4l2";
    case CameraBackend::kLibcamera:
      return "libcamera";
    case CameraBackend::kReplay:
      return "replay";
    case CameraBackend::kSim:
      return "sim";
  }
  return "?";
}

const char* to_string(ModbusTransport transport) {
  return transport == ModbusTransport::kTcp ? "tcp" : "rtu";
}

}  // namespace dentmark::board
