#pragma once
// Rendered sequences kept in the build tree between test runs: ray tracing a 1280 x 1024
// sequence takes tens of seconds, the tracker well under one. A sequence is keyed by the
// renderer's description of its options, so changed options render anew.

#include <filesystem>
#include <functional>
#include <string>

#include "dentmark/sim/stereo/sequence_writer.h"
#include "dentmark/sim/stereo_raytrace/ray_sequence.h"

namespace dentmark::track::testing {

inline std::filesystem::path sequence_cache() {
#ifdef DENTMARK_SEQUENCE_CACHE
  return DENTMARK_SEQUENCE_CACHE;
#else
  return std::filesystem::temp_directory_path() / "dentmark-sequence-cache";
#endif
}

inline std::filesystem::path cached(const std::string& name, const std::string& key,
                                    const std::function<void(const std::filesystem::path&)>& render) {
  const auto dir = sequence_cache() / (name + "-" + std::to_string(std::hash<std::string>{}(key)));
  if (std::filesystem::exists(dir / "truth.csv")) return dir;
  std::filesystem::create_directories(sequence_cache());
  try {
    render(dir);  // into a sibling folder, renamed into place when whole
  } catch (const std::exception&) {
    // Another test process (ctest -j) rendered the same sequence first: use its copy.
    if (!std::filesystem::exists(dir / "truth.csv")) throw;
  }
  return dir;
}

inline std::filesystem::path ray_traced(const std::string& name, const sim::raytrace::RaySequenceOptions& o) {
  return cached("ray-" + name, sim::raytrace::describe(o),
                [&](const std::filesystem::path& d) { sim::raytrace::write_ray_sequence(o, d); });
}

// sim/stereo's sequences have no description; the key lists the options the tests set.
inline std::filesystem::path polygon_rendered(const std::string& name,
                                              const sim::stereo::SequenceOptions& o) {
  const std::string key = std::to_string(o.width) + "x" + std::to_string(o.height) + " f" +
                          std::to_string(o.focal_px) + " s" + std::to_string(o.seconds) + " fps" +
                          std::to_string(o.fps) + " v" + std::to_string(o.speed) + " occ" +
                          std::to_string(o.occlude) + " stop" + std::to_string(o.stop_at) + "/" +
                          std::to_string(o.stop_for) + " seed" + std::to_string(o.seed);
  return cached("poly-" + name, key,
                [&](const std::filesystem::path& d) { sim::stereo::write_sequence(o, d); });
}

}  // namespace dentmark::track::testing
