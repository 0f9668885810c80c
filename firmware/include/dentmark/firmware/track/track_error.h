#pragma once
// Bad input to the tracker (unreadable or malformed files, seeds outside the image,
// too few usable features). what() is one line naming the file and the field, line or
// seed; the tools exit with code 2 on it.

#include <stdexcept>
#include <string>

namespace dentmark::track {

class TrackError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace dentmark::track
