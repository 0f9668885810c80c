#pragma once
// Runs an external program (bmaptool) without a shell and collects what it printed.

#include <string>
#include <vector>

namespace dentmark::flash {

struct ToolResult {
  int exit_code = -1;  // 128 + signal when it was killed
  std::string output;  // stdout and stderr, interleaved
};

// Throws FlashError when the program cannot be started (naming it and the reason).
ToolResult run_tool(const std::vector<std::string>& argv);

}  // namespace dentmark::flash
