// `dentmark flash IMAGE DEVICE`: writes an edge box image to a disk (or a file) with
// bmaptool and verifies it (docs/deploy.md). Thin: parse, run flash::flash_image, report.
#include <cstdio>
#include <memory>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/host/flash/flash.h"

namespace dentmark::cli {

void register_flash(CLI::App& app) {
  auto opt = std::make_shared<flash::FlashOptions>();
  auto image = std::make_shared<std::string>();
  auto target = std::make_shared<std::string>();
  auto bmap = std::make_shared<std::string>();
  CLI::App* cmd =
      app.add_subcommand("flash",
                         "Write an edge box image to a disk or file with bmaptool and verify it; refuses a "
                         "mounted disk or this machine's own");
  cmd->add_option("IMAGE", *image, "Disk image (.img, or compressed: .img.xz ...)")->required();
  cmd->add_option("DEVICE", *target, "Whole block device (/dev/sdX) or a regular file")->required();
  cmd->add_option("--bmap", *bmap, "Block map (default: IMAGE.bmap)");
  cmd->add_flag("--no-bmap", opt->no_bmap,
                "Write every byte without a block map; verify by SHA-256 of the written range");
  cmd->callback([opt, image, target, bmap] {
    opt->image = *image;
    opt->target = *target;
    opt->bmap = *bmap;
    try {
      const auto r = flash::flash_image(*opt, flash::SystemView::of_this_machine());
      char line[256];
      std::snprintf(line, sizeof line,
                    ": %.1f MB image written in %.2f s, %.1f MB read back and verified in %.2f s",
                    static_cast<double>(r.image_size) / 1e6, r.write_seconds,
                    static_cast<double>(r.verified_bytes) / 1e6, r.verify_seconds);
      log::info(opt->target.string() + line +
                (r.bmap.empty() ? " (no block map)" : " (block map " + r.bmap.string() + ")"));
      exit_code() = 0;
    } catch (const std::exception& e) {
      log::error(e.what());
      exit_code() = 1;
    }
  });
}

}  // namespace dentmark::cli
