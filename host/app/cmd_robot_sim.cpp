#include "commands.h"

namespace dentmark::cli {

void register_robot_sim(CLI::App& /*app*/) {}

}  // namespace dentmark::cli
