#include "dentmark/common/yaml_file.h"

#include <opencv2/core.hpp>
#include <string>
#include <system_error>

namespace dentmark::files {
namespace {

// OpenCV's parser names the place as "<file>(<line>): <what>" in the exception's message;
// that line and what, or its bare reason where the message has no place.
std::string parse_problem(const cv::Exception& e, const std::string& file) {
  const auto at = e.msg.find(file + "(");
  if (at == std::string::npos) return e.err;
  std::string rest = e.msg.substr(at + file.size() + 1);
  const auto close = rest.find("): ");
  if (close == std::string::npos) return e.err;
  std::string what = rest.substr(close + 3);
  while (!what.empty() && (what.back() == '\n' || what.back() == '\'')) what.pop_back();
  return "line " + rest.substr(0, close) + ": " + what;
}

}  // namespace

cv::FileStorage open_yaml(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw FileError(path, "no such file");
  cv::FileStorage fs;
  try {
    if (!fs.open(file, cv::FileStorage::READ)) throw FileError(path, "cannot open");
  } catch (const cv::Exception& e) {
    throw FileError(path, "not readable as OpenCV FileStorage YAML (" + parse_problem(e, file) + ")");
  }
  return fs;
}

}  // namespace dentmark::files
