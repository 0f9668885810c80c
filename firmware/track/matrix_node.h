#pragma once
// Guards an OpenCV FileStorage matrix node before reading it: OpenCV allocates
// rows × cols as declared before it looks at the data, so a corrupted file could ask
// for gigabytes. Private to firmware/track.

#include <opencv2/core.hpp>
#include <string>

#include "dentmark/firmware/track/track_error.h"

namespace dentmark::track::detail {

inline void check_matrix_node(const cv::FileNode& node, const std::string& file, const std::string& name,
                              double max_elements) {
  if (!node.isMap()) return;  // a plain sequence: OpenCV sizes it from the data itself
  const cv::FileNode rows = node["rows"], cols = node["cols"], data = node["data"];
  if (rows.empty() || cols.empty() || data.empty() || !rows.isInt() || !cols.isInt() || !data.isSeq())
    throw TrackError(file + ": field " + name + " is not an OpenCV matrix");
  const double n = static_cast<double>(static_cast<int>(rows)) * static_cast<int>(cols);
  if (!(n >= 1 && n <= max_elements) || n != static_cast<double>(data.size()))
    throw TrackError(file + ": field " + name + ": rows × cols must match its data (at most " +
                     std::to_string(static_cast<long>(max_elements)) + " values)");
}

}  // namespace dentmark::track::detail
