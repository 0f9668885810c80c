#include "dentmark/sim/robot/robot_record.h"

#include <nlohmann/json.hpp>
#include <stdexcept>

#include "dentmark/common/atomic_file.h"

namespace dentmark::sim::robot {
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
  try {
    files::write_atomically(path, doc.dump() + "\n");
  } catch (const files::FileError& e) {
    throw std::runtime_error(e.what());
  }
}

}  // namespace dentmark::sim::robot
