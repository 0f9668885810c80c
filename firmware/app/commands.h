#pragma once
// Subcommands of dentmark-edge. Each register_* adds its subcommand(s) to the app and
// is implemented in its own cmd_*.cpp; the callbacks set the process exit code.

#include <CLI/CLI.hpp>

namespace dentmark::edge {

// Exit code of the subcommand that ran (set by its callback).
int& exit_code();

// `dentmark-edge run --board FILE`: the daemon (also the default with --board).
void register_run(CLI::App& app);
// `dentmark-edge track ...`: offline replay through the tracker (seeds or a panel model).
void register_track(CLI::App& app);
// `dentmark-edge teach ...`: a panel model for the seedless start.
void register_teach(CLI::App& app);
// `dentmark-edge simulate ...`: the station's twin end to end (Table I scenarios).
void register_simulate(CLI::App& app);
// `dentmark-edge calibrate stereo|robot ...`: the station's calibration files.
void register_calibrate(CLI::App& app);
// `dentmark-edge selftest --board FILE ...`: the box's health check.
void register_selftest(CLI::App& app);

}  // namespace dentmark::edge
