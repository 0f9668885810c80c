#pragma once
// Writes a disk image to a device or a file with bmaptool, then verifies what was
// written (dentmark flash, docs/deploy.md):
//   1. the target passes check_target (not mounted, not this machine's disk, ...);
//   2. 'bmaptool copy' writes the image's mapped blocks, checking each range of the
//      image against the block map's checksum as it reads it (a corrupt image fails
//      here), or, with no_bmap, writes every byte ('bmaptool copy --nobmap');
//   3. the written blocks are read back and compared: each mapped range's checksum
//      with the map's, or with no_bmap the SHA-256 of the image's length of the target
//      with the image's own.
// A regular-file target is written into a temporary file beside it and renamed over
// it only once verified (files::write_atomically_with), so a failure leaves the old
// file (or none), never half an image. A block device is written in place.

#include <cstdint>
#include <filesystem>
#include <string>

#include "dentmark/host/flash/target_check.h"

namespace dentmark::flash {

struct FlashOptions {
  std::filesystem::path image;
  std::filesystem::path target;
  std::filesystem::path bmap;  // empty: IMAGE.bmap (see find_bmap)
  bool no_bmap = false;        // write and verify every byte, without a block map
  std::string bmaptool = "bmaptool";
};

struct FlashReport {
  TargetKind kind = TargetKind::kNewFile;
  std::filesystem::path bmap;        // the map used; empty with no_bmap
  std::uint64_t image_size = 0;      // bytes the target holds afterwards
  std::uint64_t verified_bytes = 0;  // bytes read back and compared
  double write_seconds = 0;
  double verify_seconds = 0;
};

// The block map of 'image': IMAGE.bmap, or for a compressed IMAGE.xz/.gz/.bz2/.zst
// also the uncompressed name's .bmap. Empty when there is none.
std::filesystem::path find_bmap(const std::filesystem::path& image);

// Flashes as described above; throws FlashError naming the file and the problem.
FlashReport flash_image(const FlashOptions& options, const SystemView& system);

}  // namespace dentmark::flash
