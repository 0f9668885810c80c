// dentmark: the host CLI. Thin: parse arguments, call a library, report.

#include "commands.h"
#include "dentmark/common/command_line.h"
#include "dentmark/common/huge_pages.h"
#include "dentmark/common/version.h"

namespace dentmark::cli {
int& exit_code() {
  static int code = 0;
  return code;
}
}  // namespace dentmark::cli

int main(int argc, char** argv) {
  dentmark::prepare_heap_for_big_jobs();
  CLI::App app{
      "dentmark: finds dents and bumps on car body panel scans and sends them to the marking station",
      "dentmark"};
  app.set_version_flag("--version", std::string("dentmark ") + dentmark::kVersion);
  app.require_subcommand(1);
  CLI::App* synth =
      app.add_subcommand("synth", "Synthesise test data (scans, stereo sequences) with ground truth");
  synth->require_subcommand(1);
  dentmark::cli::register_scan(app, *synth);
  dentmark::cli::register_link(app);
  dentmark::cli::register_robot_sim(app);
  dentmark::cli::register_stereo(app, *synth);
  dentmark::cli::register_update(app);
  dentmark::cli::register_flash(app);
  return dentmark::run_command_line(app, argc, argv, dentmark::cli::exit_code());
}
