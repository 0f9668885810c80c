// `dentmark-edge track` and `dentmark-edge teach`: offline tracker tools (issue: tracker).
#include "commands.h"

namespace dentmark::edge {

void register_track(CLI::App& /*app*/) {}

}  // namespace dentmark::edge
