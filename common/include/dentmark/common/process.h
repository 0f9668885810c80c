#pragma once
// Runs another program (bmaptool, ssh, scp) without a shell and collects what it
// printed: the tools the host drives for flashing and updating a box.

#include <stdexcept>
#include <string>
#include <vector>

namespace dentmark::process {

class ProcessError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Result {
  int exit_code = -1;      // 128 + signal when it was killed
  std::string output;      // stdout and stderr, interleaved
  bool timed_out = false;  // killed (SIGKILL) after the timeout
};

// argv[0] is looked up on PATH (unless it names a path). timeout <= 0: wait as long as
// it runs. Throws ProcessError naming the program when it is not found or cannot start.
Result run(const std::vector<std::string>& argv, double timeout = 0.0);

}  // namespace dentmark::process
