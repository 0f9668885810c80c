#pragma once
// Subcommands of the host CLI `dentmark`. Each register_* lives in its own cmd_*.cpp;
// callbacks store the process exit code in exit_code().

#include <CLI/CLI.hpp>

namespace dentmark::cli {

int& exit_code();

// detect, synth scan, eval (scan processing)
void register_detect(CLI::App& app);
// send, inspect (host-to-edge link and protocol files)
void register_link(CLI::App& app);
// robot-sim, synth stereo (station simulation)
void register_sim(CLI::App& app);

}  // namespace dentmark::cli
