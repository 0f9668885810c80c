#include "dentmark/firmware/track/sequence.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "dentmark/common/image/png_io.h"
#include "dentmark/firmware/track/track_error.h"
#include "matrix_node.h"

namespace dentmark::track {
namespace fs = std::filesystem;
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream is(line);
  while (std::getline(is, field, ',')) out.push_back(trim(field));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

bool parse_long(const std::string& s, long& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_double(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && std::isfinite(v);
}

}  // namespace

Sequence load_sequence(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw TrackError(dir.string() + ": not a directory");
  Sequence seq;
  seq.dir = dir;
  seq.calibration = load_stereo_calibration(dir / "stereo.yaml");

  const fs::path csv = dir / "frames.csv";
  std::ifstream in(csv);
  if (!in) throw TrackError(csv.string() + ": cannot open");
  std::string line;
  long line_no = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = trim(line);
    if (t.empty()) continue;
    const auto f = split_csv(t);
    const std::string where = csv.string() + ":" + std::to_string(line_no) + ": ";
    if (!header) {
      if (f.size() != 4 || f[0] != "index" || f[1] != "t" || f[2] != "left" || f[3] != "right")
        throw TrackError(where + "header must be 'index,t,left,right'");
      header = true;
      continue;
    }
    if (f.size() != 4) throw TrackError(where + "expected 4 fields, found " + std::to_string(f.size()));
    FrameEntry e;
    if (!parse_long(f[0], e.index)) throw TrackError(where + "index '" + f[0] + "' is not an integer");
    if (!parse_double(f[1], e.t)) throw TrackError(where + "t '" + f[1] + "' is not a finite number");
    if (f[2].empty() || f[3].empty()) throw TrackError(where + "empty image path");
    if (!seq.frames.empty() && !(e.t > seq.frames.back().t))
      throw TrackError(where + "t must increase (previous " + std::to_string(seq.frames.back().t) + ")");
    e.left = fs::path(f[2]).is_absolute() ? fs::path(f[2]) : dir / f[2];
    e.right = fs::path(f[3]).is_absolute() ? fs::path(f[3]) : dir / f[3];
    seq.frames.push_back(e);
  }
  if (!header) throw TrackError(csv.string() + ": empty (needs header 'index,t,left,right')");
  if (seq.frames.empty()) throw TrackError(csv.string() + ": no frames");
  return seq;
}

std::vector<cv::Point2f> load_seeds(const fs::path& path, cv::Size size) {
  const std::string file = path.string();
  cv::FileStorage fs;
  try {
    if (!fs.open(file, cv::FileStorage::READ)) throw TrackError(file + ": cannot open");
  } catch (const cv::Exception& e) {
    throw TrackError(file + ": not readable as OpenCV FileStorage YAML (" + e.err + ")");
  }
  const cv::FileNode node = fs["seeds_right"];
  if (node.empty() || node.isNone()) throw TrackError(file + ": field seeds_right is missing");
  detail::check_matrix_node(node, file, "seeds_right", 2 * 4096);
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception&) {
    throw TrackError(file + ": field seeds_right is not an OpenCV matrix");
  }
  if (m.channels() == 2) m = m.reshape(1, static_cast<int>(m.total()));
  if (m.empty() || m.cols != 2) throw TrackError(file + ": field seeds_right must be an N x 2 matrix");
  cv::Mat d;
  m.convertTo(d, CV_64F);
  std::vector<cv::Point2f> seeds;
  for (int i = 0; i < d.rows; ++i) {
    const double x = d.at<double>(i, 0), y = d.at<double>(i, 1);
    if (!std::isfinite(x) || !std::isfinite(y) || x < 0 || y < 0 || x > size.width - 1 ||
        y > size.height - 1) {
      std::ostringstream os;
      os << file << ": seeds_right row " << i << " (" << x << ", " << y << ") is outside the " << size.width
         << "x" << size.height << " image";
      throw TrackError(os.str());
    }
    seeds.emplace_back(static_cast<float>(x), static_cast<float>(y));
  }
  return seeds;
}

cv::Mat load_grey(const fs::path& path, cv::Size expected) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw TrackError(path.string() + ": no such file");
  cv::Mat img;
  try {
    img = image::read_png(path.string());
  } catch (const image::ImageError& e) {
    throw TrackError(std::string(e.what()) + " (unreadable image)");
  }
  if (img.size() != expected) {
    std::ostringstream os;
    os << path.string() << ": image is " << img.cols << "x" << img.rows << ", stereo.yaml says "
       << expected.width << "x" << expected.height;
    throw TrackError(os.str());
  }
  if (img.depth() == CV_16U) img.convertTo(img, CV_8U, 1.0 / 256.0);
  if (img.depth() != CV_8U) throw TrackError(path.string() + ": unsupported pixel type (need 8 or 16 bit)");
  if (img.channels() == 3)
    cv::cvtColor(img, img, cv::COLOR_BGR2GRAY);
  else if (img.channels() != 1)
    throw TrackError(path.string() + ": unsupported channel count");
  return img;
}

}  // namespace dentmark::track
