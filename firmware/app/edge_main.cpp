// dentmark-edge: the edge box daemon and its offline tools. Thin: parse, call, report.
#include "commands.h"
#include "dentmark/common/command_line.h"
#include "dentmark/common/version.h"

namespace dentmark::edge {
int& exit_code() {
  static int code = 0;
  return code;
}
}  // namespace dentmark::edge

int main(int argc, char** argv) {
  CLI::App app{"dentmark-edge: tracks the moving panel and marks its defects", "dentmark-edge"};
  app.set_version_flag("--version", std::string("dentmark-edge ") + dentmark::kVersion);
  app.require_subcommand(1);
  dentmark::edge::register_run(app);
  dentmark::edge::register_track(app);
  dentmark::edge::register_teach(app);
  dentmark::edge::register_simulate(app);
  dentmark::edge::register_calibrate(app);
  dentmark::edge::register_selftest(app);
  return dentmark::run_command_line(app, argc, argv, dentmark::edge::exit_code());
}
