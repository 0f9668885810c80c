#pragma once
// Minimal line logger for the executables: "<UTC time> <level> <message>" on stderr.
// One write(2) per line so lines from several threads never interleave.

#include <string>

namespace dentmark::log {

enum class Level { kDebug = 0, kInfo = 1, kWarn = 2, kError = 3 };

void set_level(Level level);
Level level();
void write(Level level, const std::string& message);

inline void debug(const std::string& m) {
  write(Level::kDebug, m);
}
inline void info(const std::string& m) {
  write(Level::kInfo, m);
}
inline void warn(const std::string& m) {
  write(Level::kWarn, m);
}
inline void error(const std::string& m) {
  write(Level::kError, m);
}

}  // namespace dentmark::log
