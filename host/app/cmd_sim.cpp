#include "commands.h"

namespace dentmark::cli {

void register_sim(CLI::App& /*app*/) {}

}  // namespace dentmark::cli
