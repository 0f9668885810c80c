// `dentmark update --to [USER@]HOST BUNDLE`: a signed RAUC bundle onto an edge box
// (host/update/box_update.h). Exit 0: the new slot runs and was marked good; 1: the box
// refused the bundle or rolled back to the old slot; 3: the box did not settle in time.
#include <iostream>
#include <memory>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/host/update/box_update.h"

namespace dentmark::cli {
namespace {

struct UpdateArgs {
  update::BoxAddress box;
  std::string bundle;
  update::UpdateOptions options;
};

int run_update(UpdateArgs& args) {
  args.options.progress = [](const std::string& line) { std::cout << "update: " << line << std::endl; };
  update::UpdateResult r;
  try {
    r = update::update_box(args.box, args.bundle, args.options);
  } catch (const update::UpdateError& e) {
    log::error(e.what());
    return 1;
  } catch (const std::exception& e) {
    log::error(e.what());
    return 1;
  }
  const std::string took = " (" + std::to_string(static_cast<int>(r.seconds)) + " s)";
  switch (r.verdict) {
    case update::Verdict::kUpdated:
      std::cout << "update: " << args.box.destination << " runs " << r.new_slot
                << ", health check passed, marked good" << took << std::endl;
      return 0;
    case update::Verdict::kRolledBack:
      log::error(args.box.destination + ": the update did not hold: the box runs " + r.old_slot + " again (" +
                 r.detail + ")" + took);
      return 1;
    case update::Verdict::kNewSlotBad:
    case update::Verdict::kWaiting:
      break;
  }
  log::error(args.box.destination + ": not settled within " +
             std::to_string(static_cast<int>(args.options.timeout)) +
             " s (last seen: " + (r.detail.empty() ? "no answer" : r.detail) + ")");
  return 3;
}

}  // namespace

void register_update(CLI::App& app) {
  auto args = std::make_shared<UpdateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "update",
      "Install a RAUC bundle on an edge box over ssh, reboot it into the new slot and wait until it "
      "is marked good (or fell back)");
  cmd->add_option("--to", args->box.destination, "The box: [USER@]HOST (ssh key login)")->required();
  cmd->add_option("bundle", args->bundle, "RAUC bundle (.raucb) made by scripts/build-bundle")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--ssh-port", args->box.ssh_port, "ssh port")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  cmd->add_option("-i,--identity", args->box.identity, "ssh private key");
  cmd->add_option("-o,--ssh-option", args->box.ssh_options, "More ssh/scp -o options (repeatable)");
  cmd->add_option("--remote-file", args->options.remote_file, "Where the bundle goes on the box")
      ->capture_default_str();
  cmd->add_flag("--allow-downgrade", args->options.allow_downgrade,
                "Install a bundle older than the running system (the box refuses one otherwise)");
  cmd->add_option("--timeout", args->options.timeout, "s for the whole update")
      ->check(CLI::Range(10.0, 86400.0))
      ->capture_default_str();
  cmd->add_option("--poll", args->options.poll_period, "s between looks at the rebooting box")
      ->check(CLI::Range(0.2, 60.0))
      ->capture_default_str();
  cmd->callback([args] { exit_code() = run_update(*args); });
}

}  // namespace dentmark::cli
