#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "dentmark/firmware/board/board_config.h"

namespace dentmark::board {
namespace {

const std::string kSource = DENTMARK_SOURCE_DIR;

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

std::string rpi5_text() {
  return read_text(kSource + "/boards/raspberrypi/rpi5/board.yaml");
}

// Replaces the first occurrence of 'from' in the rpi5 board text.
std::string rpi5_with(const std::string& from, const std::string& to) {
  std::string s = rpi5_text();
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

// Parses and returns the error, failing the test if parsing succeeds.
BoardError parse_error(const std::string& text) {
  try {
    parse_board_config(text, "test.yaml");
  } catch (const BoardError& e) {
    return e;
  }
  ADD_FAILURE() << "expected a BoardError";
  return BoardError("", 0, "", "");
}

TEST(BoardConfig, ShippedBoardsLoad) {
  for (const char* b :
       {"raspberrypi/rpi5", "nxp/imx8mp-evk", "qemu/virt-aarch64", "qemu/virt-aarch64-guest"}) {
    const std::string path = kSource + "/boards/" + b + "/board.yaml";
    const BoardConfig cfg = load_board_config(path);
    EXPECT_EQ(cfg.vendor + "/" + cfg.name, b);
    EXPECT_EQ(cfg.cpu_arch, "aarch64");
    EXPECT_FALSE(cfg.gpio.sprayer_valve.name.empty());
    EXPECT_TRUE(cfg.limits.contains(Eigen::Vector3d(0.3, 0.0, 0.5))) << b;
    EXPECT_FALSE(cfg.limits.contains(Eigen::Vector3d(3.0, 0.0, 0.5))) << b;
  }
}

TEST(BoardConfig, Rpi5Values) {
  const BoardConfig cfg = parse_board_config(rpi5_text(), "rpi5");
  EXPECT_EQ(cfg.camera.backend, CameraBackend::kLibcamera);
  EXPECT_EQ(cfg.modbus.transport, ModbusTransport::kTcp);
  EXPECT_EQ(cfg.modbus.host, "192.168.10.20");
  EXPECT_EQ(cfg.modbus.port, 502);
  EXPECT_TRUE(cfg.gpio.estop.active_low);
  EXPECT_EQ(cfg.gpio.sprayer_valve.name, "GPIO17");
  EXPECT_DOUBLE_EQ(cfg.limits.max_speed, 0.25);
  EXPECT_DOUBLE_EQ(cfg.camera.max_skew, 0.002);
  EXPECT_EQ(cfg.link.port, 7878);
  EXPECT_DOUBLE_EQ(cfg.calibration.verify_tolerance, 0.002);
}

TEST(BoardConfig, CalibrationSectionIsOptional) {
  std::string text = rpi5_text();
  text = text.substr(0, text.find("calibration:"));
  EXPECT_DOUBLE_EQ(parse_board_config(text, "test.yaml").calibration.verify_tolerance, 0.002);
  text += "calibration: { verify_tolerance: 0.0015 }\n";
  EXPECT_DOUBLE_EQ(parse_board_config(text, "test.yaml").calibration.verify_tolerance, 0.0015);
}

TEST(BoardConfig, RtuBoard) {
  const BoardConfig cfg = load_board_config(kSource + "/boards/nxp/imx8mp-evk/board.yaml");
  EXPECT_EQ(cfg.modbus.transport, ModbusTransport::kRtu);
  EXPECT_EQ(cfg.modbus.device, "/dev/ttymxc1");
  EXPECT_EQ(cfg.modbus.baud, 115200);
  EXPECT_EQ(cfg.modbus.parity, 'N');
  EXPECT_EQ(cfg.camera.backend, CameraBackend::kV4l2);
}

TEST(BoardConfig, ErrorsNameKeyAndLine) {
  struct Case {
    std::string from, to, key, problem;
  };
  const Case cases[] = {
      {"max_speed: 0.25", "max_speed: fast", "limits.max_speed", "expected a number"},
      {"max_speed: 0.25", "max_speed: -1", "limits.max_speed", "out of range"},
      {"port: 502", "port: 70000", "modbus.port", "out of range"},
      {"backend: libcamera", "backend: webcam", "camera.backend", "not one of"},
      {"transport: tcp", "transport: can", "modbus.transport", "not tcp or rtu"},
      {"{ line: \"GPIO17\", active_low: false }", "{ active_low: false }", "gpio.sprayer_valve.line",
       "missing required key"},
      {"{ line: \"GPIO27\", active_low: true }", "{ line: \"GPIO27\", active_low: maybe }",
       "gpio.estop.active_low", "expected true or false"},
      {"max_skew: 0.002", "max_skw: 0.002", "camera.max_skw", "unknown key"},
      {"workspace_min: [-0.60, -0.80, -0.10]", "workspace_min: [-0.60, -0.80]", "limits.workspace_min",
       "list of 3"},
      {"workspace_min: [-0.60, -0.80, -0.10]", "workspace_min: [-0.60, -0.80, 2.0]", "limits.workspace_min",
       "below"},
      {"\"GPIO22\"", "\"GPIO17\"", "gpio", "different lines"},
      {"verify_tolerance: 0.002", "verify_tolerance: 0.5", "calibration.verify_tolerance", "out of range"},
      {"verify_tolerance: 0.002", "verify_tol: 0.002", "calibration.verify_tol", "unknown key"},
  };
  for (const Case& c : cases) {
    const BoardError e = parse_error(rpi5_with(c.from, c.to));
    EXPECT_EQ(e.key(), c.key) << e.what();
    EXPECT_NE(std::string(e.what()).find(c.problem), std::string::npos) << e.what();
    EXPECT_GT(e.line(), 0) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("test.yaml:", 0), 0u) << e.what();
  }
}

TEST(BoardConfig, ErrorLineIsTheOffendingLine) {
  const std::string text = rpi5_with("max_speed: 0.25", "max_speed: fast");
  const BoardError e = parse_error(text);
  std::istringstream lines(text);
  std::string line;
  for (int i = 0; i < e.line(); ++i) std::getline(lines, line);
  EXPECT_NE(line.find("max_speed: fast"), std::string::npos) << "line " << e.line() << ": " << line;
}

TEST(BoardConfig, SyntaxErrorsAndEmptyFiles) {
  EXPECT_EQ(parse_error("board: [unclosed\n").key(), "(syntax)");
  EXPECT_EQ(parse_error("").key(), "(root)");
  EXPECT_EQ(parse_error("- a\n- b\n").key(), "");  // root must be a mapping
  EXPECT_THROW(load_board_config("/nonexistent/board.yaml"), BoardError);
}

TEST(BoardConfig, EveryTruncationFailsCleanly) {
  // Cutting the file anywhere either still parses (a prefix can be complete only at
  // the very end) or throws BoardError; nothing else escapes.
  const std::string text = rpi5_text();
  for (std::size_t n = 0; n < text.size(); n += 7) {
    try {
      parse_board_config(text.substr(0, n), "cut.yaml");
    } catch (const BoardError&) {
    }
  }
}

}  // namespace
}  // namespace dentmark::board
