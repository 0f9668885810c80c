#include "dentmark/host/flash/flash.h"

#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <sstream>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/process.h"
#include "dentmark/host/flash/bmap.h"

namespace dentmark::flash {
namespace fs = std::filesystem;
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

constexpr std::array<std::string_view, 5> kCompressed = {".xz", ".gz", ".bz2", ".zst", ".lz4"};

bool is_compressed(const fs::path& image) {
  for (auto ext : kCompressed)
    if (image.extension() == ext) return true;
  return false;
}

// bmaptool's last error message (it colours "ERROR" and may print a traceback first),
// else its last line, for an error of ours.
std::string tool_message(const process::Result& r) {
  std::string plain;
  for (std::size_t i = 0; i < r.output.size(); ++i) {
    if (r.output[i] == '\x1b') {  // ANSI escape: ESC [ ... letter
      while (i < r.output.size() && !std::isalpha(static_cast<unsigned char>(r.output[i]))) ++i;
      continue;  // past the final letter too
    }
    plain += r.output[i];
  }
  std::istringstream in(plain);
  std::string last, error;
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    const auto e = line.find("ERROR: ");
    if (e != std::string::npos) error = line.substr(e + 7);
    last = line;
  }
  if (!error.empty()) return error;
  return last.empty() ? "exit code " + std::to_string(r.exit_code) : last;
}

void bmaptool_copy(const FlashOptions& o, const fs::path& bmap, const fs::path& dest) {
  std::vector<std::string> argv{o.bmaptool, "--quiet", "copy"};
  if (bmap.empty())
    argv.push_back("--nobmap");
  else
    argv.insert(argv.end(), {"--bmap", bmap.string()});
  argv.insert(argv.end(), {o.image.string(), dest.string()});
  process::Result r;
  try {
    r = process::run(argv);
  } catch (const process::ProcessError& e) {
    throw FlashError(std::string(e.what()) + " (install bmap-tools: scripts/setup-deps)");
  }
  if (r.exit_code != 0)
    throw FlashError(o.image.string() + ": writing to " + o.target.string() + " failed: " + tool_message(r));
}

// Reads back what was written: the mapped ranges against the map, or every byte of
// the image's length against the image itself.
std::uint64_t verify(const FlashOptions& o, const fs::path& written, const fs::path& bmap,
                     std::uint64_t image_size) {
  if (!bmap.empty()) return verify_against_bmap(written, read_bmap(bmap));
  const std::string want = sha256_of_prefix(o.image, image_size);
  const std::string got = sha256_of_prefix(written, image_size);
  if (got != want)
    throw FlashError(o.target.string() + ": verification failed: the first " + std::to_string(image_size) +
                     " bytes read back with SHA-256 " + got + ", " + o.image.string() + " has " + want);
  return image_size;
}

}  // namespace

fs::path find_bmap(const fs::path& image) {
  std::error_code ec;
  fs::path candidate = image;
  candidate += ".bmap";
  if (fs::is_regular_file(candidate, ec)) return candidate;
  if (is_compressed(image)) {
    candidate = image.parent_path() / image.stem();
    candidate += ".bmap";
    if (fs::is_regular_file(candidate, ec)) return candidate;
  }
  return {};
}

FlashReport flash_image(const FlashOptions& o, const SystemView& system) {
  std::error_code ec;
  if (!fs::is_regular_file(o.image, ec))
    throw FlashError(o.image.string() + ": " +
                     (fs::exists(o.image, ec) ? "not a regular file" : "no such image"));
  FlashReport report;
  if (!o.no_bmap) {
    report.bmap = o.bmap.empty() ? find_bmap(o.image) : o.bmap;
    if (report.bmap.empty())
      throw FlashError(o.image.string() + ": no block map " + o.image.string() +
                       ".bmap beside it (make one with 'bmaptool create', give it with "
                       "--bmap, or write every byte unchecked by the map with --no-bmap)");
    if (!fs::is_regular_file(report.bmap, ec)) throw FlashError(report.bmap.string() + ": no such block map");
  } else if (is_compressed(o.image)) {
    throw FlashError(o.image.string() +
                     ": --no-bmap verifies against the image's own bytes, so it needs an "
                     "uncompressed image");
  }
  report.image_size = report.bmap.empty() ? fs::file_size(o.image) : read_bmap(report.bmap).image_size;
  report.kind = check_target(o.target, system);

  if (report.kind == TargetKind::kBlockDevice) {
    auto t0 = std::chrono::steady_clock::now();
    bmaptool_copy(o, report.bmap, o.target);
    report.write_seconds = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    report.verified_bytes = verify(o, o.target, report.bmap, report.image_size);
    report.verify_seconds = seconds_since(t0);
    return report;
  }

  // A regular file: written and verified beside the target, then renamed over it.
  files::write_atomically_with(o.target, [&](const fs::path& temp) {
    auto t0 = std::chrono::steady_clock::now();
    bmaptool_copy(o, report.bmap, temp);
    report.write_seconds = seconds_since(t0);
    const auto written_size = fs::file_size(temp);
    if (written_size != report.image_size)
      throw FlashError(o.target.string() + ": bmaptool wrote " + std::to_string(written_size) +
                       " bytes, the image has " + std::to_string(report.image_size));
    t0 = std::chrono::steady_clock::now();
    report.verified_bytes = verify(o, temp, report.bmap, report.image_size);
    report.verify_seconds = seconds_since(t0);
    // The new file keeps the old one's permissions.
    struct stat st {};
    if (report.kind == TargetKind::kRegularFile && ::stat(o.target.c_str(), &st) == 0)
      ::chmod(temp.c_str(), st.st_mode & 07777);
  });
  return report;
}

}  // namespace dentmark::flash
