#include "commands.h"

namespace dentmark::cli {

void register_detect(CLI::App& /*app*/) {}

}  // namespace dentmark::cli
