#include "dentmark/sim/robot/robot_record.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace dentmark::sim {
namespace {

nlohmann::json pose_json(const Transform& T) {
  const Eigen::Vector3d t = T.translation();
  const Eigen::Vector3d r = rotation_vector(T);
  return {{"t", {t.x(), t.y(), t.z()}}, {"r", {r.x(), r.y(), r.z()}}};
}

}  // namespace

void write_robot_record(const std::string& path, const std::vector<TipSample>& trajectory,
                        const std::vector<SprayRecord>& sprays) {
  nlohmann::json doc;
  doc["units"] = "m, rad, s";
  doc["trajectory"] = nlohmann::json::array();
  for (const auto& s : trajectory)
    doc["trajectory"].push_back({{"time", s.time},
                                 {"tip", pose_json(s.T_base_tip)},
                                 {"tool", pose_json(s.T_base_tool)},
                                 {"speed", s.speed}});
  doc["sprays"] = nlohmann::json::array();
  for (const auto& s : sprays)
    doc["sprays"].push_back({{"time", s.time},
                             {"sequence", s.sequence},
                             {"duration", s.duration},
                             {"tip", pose_json(s.T_base_tip)},
                             {"tool", pose_json(s.T_base_tool)}});
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out)
      throw std::runtime_error(path + ": cannot open '" + tmp + "' for writing: " + std::strerror(errno));
    out << doc.dump() << "\n";
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      throw std::runtime_error(path + ": write failed");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot rename the temporary file: " + std::strerror(err));
  }
}

}  // namespace dentmark::sim
