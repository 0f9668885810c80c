#pragma once
// Subcommands of the host CLI `dentmark`. Each register_* lives in its own cmd_*.cpp;
// callbacks store the process exit code in exit_code().

#include <CLI/CLI.hpp>

namespace dentmark::cli {

int& exit_code();

// detect, eval, synth scan (scan processing)
void register_scan(CLI::App& app, CLI::App& synth);
// send, inspect (host-to-edge link and protocol files)
void register_link(CLI::App& app);
// robot-sim (Modbus robot simulator)
void register_robot_sim(CLI::App& app);
// synth stereo (rendered stereo sequences of the moving panel)
void register_stereo(CLI::App& app, CLI::App& synth);
// update (RAUC bundles onto an edge box over ssh)
void register_update(CLI::App& app);
// flash (edge box images to disks, with bmaptool)
void register_flash(CLI::App& app);

}  // namespace dentmark::cli
