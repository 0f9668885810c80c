#include "dentmark/firmware/calibrate/image_pairs.h"

#include <algorithm>
#include <cctype>
#include <map>
#include <regex>

#include "dentmark/firmware/calibrate/calibrate_error.h"

namespace dentmark::calibrate {

namespace fs = std::filesystem;

std::vector<ImagePair> find_image_pairs(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw CalibrateError(dir.string() + ": not a directory");
  static const std::regex re(R"(^(left|right)([0-9]{1,9})\.(png|jpg|jpeg)$)", std::regex::icase);
  std::map<long, ImagePair> pairs;
  fs::directory_iterator it(dir, ec);
  if (ec) throw CalibrateError(dir.string() + ": cannot list (" + ec.message() + ")");
  for (const fs::directory_entry& e : it) {
    if (!e.is_regular_file(ec)) continue;
    const std::string name = e.path().filename().string();
    std::smatch m;
    if (!std::regex_match(name, m, re)) continue;
    std::string side = m[1];
    std::transform(side.begin(), side.end(), side.begin(), [](unsigned char c) { return std::tolower(c); });
    const long n = std::stol(m[2]);
    ImagePair& p = pairs[n];
    p.number = n;
    fs::path& slot = side == "left" ? p.left : p.right;
    if (!slot.empty()) {
      std::string a = slot.filename().string(), b = name;
      if (b < a) std::swap(a, b);
      throw CalibrateError(dir.string() + ": " + a + " and " + b + " both carry " + side + " image number " +
                           std::to_string(n));
    }
    slot = e.path();
    if (side == "left") p.name = m[2];
  }
  std::vector<ImagePair> out;
  for (auto& [n, p] : pairs) {
    if (p.left.empty())
      throw CalibrateError(p.right.string() + ": no left image numbered " + std::to_string(n) +
                           " to pair with");
    if (p.right.empty())
      throw CalibrateError(p.left.string() + ": no right image numbered " + std::to_string(n) +
                           " to pair with");
    out.push_back(std::move(p));
  }
  if (out.empty())
    throw CalibrateError(dir.string() +
                         ": no image pairs (expected left<N>.<ext> and right<N>.<ext>, ext png, jpg or "
                         "jpeg)");
  return out;
}

}  // namespace dentmark::calibrate
