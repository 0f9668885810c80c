#include "dentmark/common/stereo_index.h"

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace dentmark::files {
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
  return !s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_double(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && std::isfinite(v);
}

}  // namespace

std::vector<StereoIndexEntry> read_stereo_index(const std::filesystem::path& dir) {
  const std::filesystem::path csv = dir / "frames.csv";
  std::ifstream in(csv);
  if (!in) throw StereoIndexError(csv.string() + ": cannot open");
  std::vector<StereoIndexEntry> out;
  std::string line;
  long line_no = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string text = trim(line);
    if (text.empty()) continue;
    const auto f = split_csv(text);
    const std::string where = csv.string() + ":" + std::to_string(line_no) + ": ";
    if (!header) {
      if (f != std::vector<std::string>{"index", "t", "left", "right"})
        throw StereoIndexError(where + "header must be 'index,t,left,right'");
      header = true;
      continue;
    }
    if (f.size() != 4) throw StereoIndexError(where + "expected 4 fields, found " + std::to_string(f.size()));
    StereoIndexEntry e;
    if (!parse_long(f[0], e.index)) throw StereoIndexError(where + "index '" + f[0] + "' is not an integer");
    if (!parse_double(f[1], e.t)) throw StereoIndexError(where + "t '" + f[1] + "' is not a finite number");
    if (f[2].empty() || f[3].empty()) throw StereoIndexError(where + "empty image path");
    if (!out.empty() && !(e.t > out.back().t))
      throw StereoIndexError(where + "t must increase (previous " + std::to_string(out.back().t) + ")");
    e.left = dir / f[2];  // an absolute path stays as it is
    e.right = dir / f[3];
    out.push_back(std::move(e));
  }
  if (!header) throw StereoIndexError(csv.string() + ": empty (needs header 'index,t,left,right')");
  if (out.empty()) throw StereoIndexError(csv.string() + ": no frames");
  return out;
}

void write_stereo_index_header(std::ostream& out) {
  out << "index,t,left,right\n";
}

void write_stereo_index_line(std::ostream& out, long index, double t, const std::string& left,
                             const std::string& right) {
  out << index << ',' << std::setprecision(12) << t << ',' << left << ',' << right << '\n';
}

}  // namespace dentmark::files
