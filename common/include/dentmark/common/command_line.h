#pragma once
// The end every command-line tool's main() shares: parse, and turn what parsing and the
// command raise into the process's exit status.

#include <CLI/CLI.hpp>
#include <exception>

#include "dentmark/common/log.h"

namespace dentmark {

// Parses argv into app, whose callbacks run the command and set exit_code. Returns 0 for
// --help and --version, 2 for a usage error (printed), 1 for a command that threw
// (logged), else exit_code.
inline int run_command_line(CLI::App& app, int argc, char** argv, const int& exit_code) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --help-all, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  } catch (const std::exception& e) {
    log::error(e.what());
    return 1;
  }
  return exit_code;
}

}  // namespace dentmark
