#pragma once
// Reading the YAML files OpenCV's FileStorage writes (calibrations, panel models, seeds):
// every reader opens them here, so every one names the problem the same way.

#include <filesystem>
#include <opencv2/core/persistence.hpp>

#include "dentmark/common/atomic_file.h"

namespace dentmark::files {

// The file open for reading. Throws FileError "<file>: no such file", "<file>: cannot
// open" or "<file>: not readable as OpenCV FileStorage YAML (line N: what)".
cv::FileStorage open_yaml(const std::filesystem::path& path);

// The same, throwing Error (a module's own error type) with the same message.
template <class Error>
cv::FileStorage open_yaml_or_throw(const std::filesystem::path& path) {
  try {
    return open_yaml(path);
  } catch (const FileError& e) {
    throw Error(e.what());
  }
}

}  // namespace dentmark::files
