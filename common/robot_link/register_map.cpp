#include "dentmark/common/robot_link/register_map.h"

#include <cstdio>
#include <string>

namespace dentmark::robot_link {

const char* to_string(Command c) {
  switch (c) {
    case Command::kIdle:
      return "idle";
    case Command::kMove:
      return "move";
    case Command::kSpray:
      return "spray";
    case Command::kAbort:
      return "abort";
  }
  return "unknown";
}

const char* to_string(State s) {
  switch (s) {
    case State::kIdle:
      return "idle";
    case State::kMoving:
      return "moving";
    case State::kSpraying:
      return "spraying";
    case State::kFault:
      return "fault";
    case State::kStopped:
      return "stopped";
  }
  return "unknown";
}

std::string fault_names(std::uint16_t faults) {
  if (faults == 0) return "none";
  std::string out;
  const auto add = [&](std::uint16_t bit, const char* name) {
    if (!(faults & bit)) return;
    if (!out.empty()) out += "|";
    out += name;
    faults = static_cast<std::uint16_t>(faults & ~bit);
  };
  add(fault::kWorkspace, "workspace");
  add(fault::kHeartbeatLost, "heartbeat_lost");
  add(fault::kBadCommand, "bad_command");
  add(fault::kAborted, "aborted");
  add(fault::kDrive, "drive");
  if (faults != 0) {
    if (!out.empty()) out += "|";
    out += "0x" + [&] {
      char buf[8];
      std::snprintf(buf, sizeof buf, "%04x", faults);
      return std::string(buf);
    }();
  }
  return out;
}

void encode_pose(const Transform& T_base_tool, std::span<std::uint16_t> regs) {
  if (regs.size() < 6) throw EncodingError("a pose needs 6 registers, got " + std::to_string(regs.size()));
  const Eigen::Vector3d p = T_base_tool.translation();
  const Eigen::Vector3d r = rotation_vector(T_base_tool);
  static constexpr const char* kNames[6] = {"x", "y", "z", "rx", "ry", "rz"};
  // Encode into a copy first so a failure leaves regs untouched.
  std::uint16_t out[6];
  for (int i = 0; i < 3; ++i) out[i] = encode_scaled_i16(p(i), kPositionScale, kNames[i]);
  for (int i = 0; i < 3; ++i) out[3 + i] = encode_scaled_i16(r(i), kRotationScale, kNames[3 + i]);
  for (int i = 0; i < 6; ++i) regs[static_cast<std::size_t>(i)] = out[i];
}

Transform decode_pose(std::span<const std::uint16_t> regs) {
  if (regs.size() < 6) throw EncodingError("a pose needs 6 registers, got " + std::to_string(regs.size()));
  Eigen::Vector3d p, r;
  for (int i = 0; i < 3; ++i) p(i) = decode_scaled_i16(regs[static_cast<std::size_t>(i)], kPositionScale);
  for (int i = 0; i < 3; ++i) r(i) = decode_scaled_i16(regs[static_cast<std::size_t>(3 + i)], kRotationScale);
  return make_transform_rotvec(r, p);
}

}  // namespace dentmark::robot_link
