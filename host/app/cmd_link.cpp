#include "commands.h"

namespace dentmark::cli {

void register_link(CLI::App& /*app*/) {}

}  // namespace dentmark::cli
