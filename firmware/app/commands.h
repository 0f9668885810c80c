#pragma once
// Subcommands of dentmark-edge. Each register_* adds its subcommand(s) to the app and
// is implemented in its own cmd_*.cpp; the callbacks set the process exit code.

#include <CLI/CLI.hpp>

namespace dentmark::edge {

// Exit code of the subcommand that ran (set by its callback).
int& exit_code();

// `dentmark-edge run --board FILE`: the daemon (also the default with --board).
void register_run(CLI::App& app);
// `dentmark-edge track ...` and `dentmark-edge teach ...`: offline tracker tools.
void register_track(CLI::App& app);
// `dentmark-edge simulate ...`: the station's twin end to end (Table I scenarios).
void register_simulate(CLI::App& app);

}  // namespace dentmark::edge
