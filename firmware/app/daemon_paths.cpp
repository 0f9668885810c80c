#include "daemon_paths.h"

#include <cstdlib>

namespace dentmark::edge {

std::string default_state_dir() {
  // StateDirectory= may list several folders separated by ':'.
  if (const char* s = std::getenv("STATE_DIRECTORY"); s && *s) {
    const std::string all(s);
    return all.substr(0, all.find(':'));
  }
  return "/var/lib/dentmark";
}

}  // namespace dentmark::edge
