// `dentmark-edge run`: the edge daemon.
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "dentmark/common/version.h"
#include "dentmark/firmware/board/board_config.h"
#include "dentmark/firmware/link/job_inbox.h"
#include "dentmark/firmware/link/link_server.h"
#include "stop_signal.h"

namespace dentmark::edge {
namespace {

struct RunOptions {
  std::string board_file;
  bool check_only = false;
  bool verbose = false;
  int port = -1;  // -1: the board's link.port; 0: any free port
  std::string key_file;
  double replay_window = 30.0;
  int max_clients = 8;
};

double wall_clock() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string describe(const board::BoardConfig& b) {
  std::ostringstream os;
  os << "board " << b.vendor << "/" << b.name << " (" << b.source << "): camera "
     << to_string(b.camera.backend) << " " << b.camera.width << "x" << b.camera.height << ", modbus "
     << to_string(b.modbus.transport) << " ";
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
  std::optional<protocol::HmacKey> key;
  if (!opt.key_file.empty()) {
    try {
      key = protocol::HmacKey::load(opt.key_file);
    } catch (const protocol::KeyFileError& e) {
      log::error(e.what());
      return 2;
    }
  }
  log::info(std::string("dentmark-edge ") + kVersion + ": " + describe(board));
  if (opt.check_only) return 0;

  // Before any thread starts, so that every thread inherits the blocked signals.
  StopSignal stop;
  link::JobInbox inbox;
  link::ServerOptions so;
  so.port = static_cast<std::uint16_t>(opt.port >= 0 ? opt.port : board.link.port);
  so.key = key ? &*key : nullptr;
  so.replay_window = opt.replay_window;
  so.max_clients = opt.max_clients;
  so.clock = wall_clock;
  link::LinkServer server(so, [&inbox](const protocol::Decoded& d, std::span<const std::uint8_t> frame) {
    return inbox.handle(d, frame, wall_clock());
  });
  try {
    server.start();
  } catch (const link::LinkServerError& e) {
    log::error(e.what());
    return 1;
  }
  log::info("link: listening on port " + std::to_string(server.port()) +
            (key ? " (HMAC-SHA-256 required, replay window " + std::to_string(opt.replay_window) + " s)"
                 : " (unauthenticated: no --key)"));
  log::info("running; SIGINT or SIGTERM stops");
  while (!stop.wait_for(std::chrono::milliseconds(200))) {
  }
  log::info("signal " + std::to_string(stop.signal_number()) + " received; shut down cleanly");
  server.stop();
  if (auto job = inbox.last_job())
    log::info("last job " + std::to_string(job->list.job_id) + " (" +
              std::to_string(job->list.defects.size()) + " defects) kept; " +
              std::to_string(inbox.jobs_received()) + " lists received");
  return 0;
}

}  // namespace

void register_run(CLI::App& app) {
  auto opt = std::make_shared<RunOptions>();
  CLI::App* run = app.add_subcommand("run", "Run the edge daemon with a board file");
  run->add_option("--board", opt->board_file, "Board file (boards/<vendor>/<board>/board.yaml)")->required();
  run->add_flag("--check", opt->check_only, "Validate the board file and exit");
  run->add_flag("-v,--verbose", opt->verbose, "Debug logging");
  run->add_option("--port", opt->port,
                  "Link port (overrides the board's link.port; 0 = any free port, logged)")
      ->check(CLI::Range(0, 65535));
  run->add_option("--key", opt->key_file, "Pre-shared HMAC-SHA-256 key file (hex); refuses unsigned frames");
  run->add_option("--replay-window", opt->replay_window, "Accepted send-time skew and replay memory, s")
      ->check(CLI::Range(0.1, 3600.0));
  run->add_option("--max-clients", opt->max_clients, "Simultaneous link clients")->check(CLI::Range(1, 256));
  run->callback([opt] { exit_code() = run_daemon(*opt); });
}

}  // namespace dentmark::edge
