#pragma once
// Bad input to a calibration (unreadable or unpaired images, a pattern that is not
// found, a malformed option). what() is one line naming the file or option; the
// calibrate commands exit with code 2 on it and write no output file.

#include <stdexcept>
#include <string>

namespace dentmark::calibrate {

class CalibrateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace dentmark::calibrate
