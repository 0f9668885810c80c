#include "dentmark/firmware/calibrate/charuco_module.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> places() {
  if (const char* env = std::getenv("DENTMARK_CHARUCO_MODULE"); env && *env) return {env};
  std::vector<fs::path> out;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) out.push_back(exe.parent_path() / ".." / "lib" / "dentmark-edge" / "dentmark-charuco.so");
  out.emplace_back(DENTMARK_CHARUCO_BUILD_PATH);
  return out;
}

// Opens one candidate; on failure appends why to 'errors' and returns nullptr.
const CharucoModule* open_module(const fs::path& path, std::string& errors) {
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle) {
    const char* why = dlerror();
    errors += "\n  " + path.string() + ": " + (why ? why : "cannot be loaded");
    return nullptr;
  }
  using Entry = const CharucoModule* (*)();
  auto entry = reinterpret_cast<Entry>(dlsym(handle, kCharucoModuleSymbol));
  const CharucoModule* module = entry ? entry() : nullptr;
  if (!module || module->abi != kCharucoModuleAbi || !module->dictionary_id || !module->dictionary_size ||
      !module->detect) {
    errors += "\n  " + path.string() + ": not a dentmark ChArUco module of this build (ABI " +
              std::to_string(kCharucoModuleAbi) + ")";
    dlclose(handle);
    return nullptr;
  }
  return module;  // never unloaded: its functions may be in use until the program ends
}

const CharucoModule* load(std::string& errors) {
  for (const fs::path& p : places())
    if (const CharucoModule* m = open_module(p, errors)) return m;
  return nullptr;
}

}  // namespace

const CharucoModule& charuco_module() {
  static std::once_flag once;
  static const CharucoModule* module = nullptr;
  static std::string errors;
  std::call_once(once, [] { module = load(errors); });
  if (!module)
    throw CalibrateError(
        "ChArUco targets need dentmark's ChArUco module (Debian package dentmark-edge-charuco), "
        "which did not load:" +
        errors);
  return *module;
}

}  // namespace dentmark::calibrate
