#pragma once
// Reading the project's JSON files (defect lists, truth files) with errors that name the
// file and the byte or field. 'Error' is the caller's exception type, constructed from
// the message.

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

namespace dentmark::json_file {

// The parsed file; throws Error "FILE: cannot open" or "FILE: byte N: not valid JSON".
template <class Error>
nlohmann::json read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open");
  std::stringstream text;
  text << in.rdbuf();
  try {
    return nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::parse_error& e) {
    throw Error(path + ": byte " + std::to_string(e.byte) + ": not valid JSON");
  }
}

// j[key] as a finite number; throws Error "WHERE.KEY: missing or not a finite number".
template <class Error>
double finite_number(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number() || !std::isfinite(j[key].get<double>()))
    throw Error(where + "." + key + ": missing or not a finite number");
  return j[key].get<double>();
}

}  // namespace dentmark::json_file
