#pragma once
// The wall-clock date stamped into files people read (calibrations, reports):
// ISO 8601 in UTC to the second, e.g. 2026-12-05T21:55:14Z.

#include <chrono>
#include <ctime>
#include <string>

namespace dentmark {

inline std::string utc_now_iso8601() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);  // gmtime() shares one buffer between threads
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return b;
}

}  // namespace dentmark
