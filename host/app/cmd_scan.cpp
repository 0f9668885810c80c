#include "commands.h"

namespace dentmark::cli {

void register_scan(CLI::App& /*app*/, CLI::App& /*synth*/) {}

}  // namespace dentmark::cli
