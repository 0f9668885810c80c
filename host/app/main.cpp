// dentmark: the host CLI. Thin: parse arguments, call a library, report.
#include <malloc.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

#include "commands.h"
#include "dentmark/common/log.h"
#include "dentmark/common/version.h"

namespace dentmark::cli {
int& exit_code() {
  static int code = 0;
  return code;
}
}  // namespace dentmark::cli

namespace {

// A 9 M-triangle scan touches ~300 MB of fresh memory. On a VM every fresh 4 KB page is
// a fault that costs ~3 ms per MB (1 s for the scan); 2 MB transparent huge pages cut
// that ~20-fold, but this kernel setting is usually 'madvise' and glibc asks for them only
// when its tunable is set, which it reads at start-up. So the command re-executes itself
// once with the tunable added. DENTMARK_HUGEPAGES=0 turns this off.
void reexec_with_huge_pages(char** argv) {
  constexpr const char* kTunable = "glibc.malloc.hugetlb=1";
  const char* off = std::getenv("DENTMARK_HUGEPAGES");
  if (off && std::strcmp(off, "0") == 0) return;
  const char* current = std::getenv("GLIBC_TUNABLES");
  if (current && std::strstr(current, "glibc.malloc.hugetlb")) return;  // set (by us or the user)
  const std::string tunables = current && *current ? std::string(current) + ":" + kTunable : kTunable;
  if (::setenv("GLIBC_TUNABLES", tunables.c_str(), 1) != 0) return;
  ::execv("/proc/self/exe", argv);
  ::unsetenv("GLIBC_TUNABLES");  // exec failed (no /proc): carry on with small pages
  if (current) ::setenv("GLIBC_TUNABLES", current, 1);
}

}  // namespace

int main(int argc, char** argv) {
  reexec_with_huge_pages(argv);
  // Big scans are processed in stages that each allocate and free tens of MB. Keep freed
  // memory in the heap for the next stage: fresh pages cost a fault and zeroing each
  // (about 1.5 GB/s on a VM, ten times slower than reusing memory).
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
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
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;  // usage error
  } catch (const std::exception& e) {
    dentmark::log::error(e.what());
    return 1;
  }
  return dentmark::cli::exit_code();
}
