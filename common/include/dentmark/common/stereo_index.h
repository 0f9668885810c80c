#pragma once
// frames.csv, the index of a recorded or rendered stereo sequence: a header
// `index,t,left,right`, then one line per pair with its frame counter, its capture time
// in seconds (strictly increasing) and the two image files, relative to the folder or
// absolute. The tracker's replays, the replay cameras and the sequence renderer all
// read or write it through here.

#include <filesystem>
#include <iosfwd>
#include <stdexcept>
#include <string>
#include <vector>

namespace dentmark::files {

class StereoIndexError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct StereoIndexEntry {
  long index = 0;
  double t = 0.0;                     // s
  std::filesystem::path left, right;  // resolved against the folder
};

// Reads DIR/frames.csv. Throws StereoIndexError naming the file and line ("…/frames.csv:3:
// t must increase …"). Blank lines are ignored; at least one pair is required.
std::vector<StereoIndexEntry> read_stereo_index(const std::filesystem::path& dir);

// The header line, and one pair's line (paths as given), for writers.
void write_stereo_index_header(std::ostream& out);
void write_stereo_index_line(std::ostream& out, long index, double t, const std::string& left,
                             const std::string& right);

}  // namespace dentmark::files
