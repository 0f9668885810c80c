#include "commands.h"

namespace dentmark::cli {

void register_stereo(CLI::App& /*app*/, CLI::App& /*synth*/) {}

}  // namespace dentmark::cli
