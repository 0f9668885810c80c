// `dentmark-edge run`: the edge daemon.
#include <memory>
#include <sstream>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/common/version.h"
#include "dentmark/firmware/board/board_config.h"
#include "stop_signal.h"

namespace dentmark::edge {
namespace {

struct RunOptions {
  std::string board_file;
  bool check_only = false;
  bool verbose = false;
};

std::string describe(const board::BoardConfig& b) {
  std::ostringstream os;
  os << "board " << b.vendor << "/" << b.name << " (" << b.source << "): camera " << to_string(b.camera.backend)
     << " " << b.camera.width << "x" << b.camera.height << ", modbus " << to_string(b.modbus.transport) << " ";
  if (b.modbus.transport == board::ModbusTransport::kTcp)
    os << b.modbus.host << ":" << b.modbus.port;
  else
    os << b.modbus.device << " " << b.modbus.baud << " " << b.modbus.parity;
  os << ", valve line '" << b.gpio.sprayer_valve.name << "', e-stop line '" << b.gpio.estop.name
     << "', link port " << b.link.port;
  return os.str();
}

int run_daemon(const RunOptions& opt) {
  if (opt.verbose) log::set_level(log::Level::kDebug);
  board::BoardConfig board;
  try {
    board = board::load_board_config(opt.board_file);
  } catch (const board::BoardError& e) {
    log::error(e.what());
    return 2;
  }
  log::info(std::string("dentmark-edge ") + kVersion + ": " + describe(board));
  if (opt.check_only) return 0;

  StopSignal stop;
  log::info("running; SIGINT or SIGTERM stops");
  while (!stop.wait_for(std::chrono::milliseconds(200))) {
  }
  log::info("signal " + std::to_string(stop.signal_number()) + " received; shut down cleanly");
  return 0;
}

}  // namespace

void register_run(CLI::App& app) {
  auto opt = std::make_shared<RunOptions>();
  CLI::App* run = app.add_subcommand("run", "Run the edge daemon with a board file");
  run->add_option("--board", opt->board_file, "Board file (boards/<vendor>/<board>/board.yaml)")->required();
  run->add_flag("--check", opt->check_only, "Validate the board file and exit");
  run->add_flag("-v,--verbose", opt->verbose, "Debug logging");
  run->callback([opt] { exit_code() = run_daemon(*opt); });
}

}  // namespace dentmark::edge
