#pragma once
// The robot's Modbus register map, shared by the edge's client (firmware/hal/robot)
// and the robot simulator (sim/robot). docs/robot-modbus.md is its specification;
// change both together.
//
// Holding registers (the edge writes them with function 0x10 in one request, so the
// robot never sees half a command): the command block. Input registers (the edge
// reads them with function 0x04): the status block. Addresses are PDU addresses
// (0-based; mbpoll -0).

#include <cstdint>
#include <span>
#include <string>

#include "dentmark/common/geometry/transform.h"
#include "dentmark/common/robot_link/word_order.h"

namespace dentmark::robot_link {

// 32-bit values in this map are high word first.
inline constexpr WordOrder kWordOrder = WordOrder::kHighWordFirst;

// Pose encoding, as a UR-style robot program reads signed 16-bit registers:
// position x, y, z in 0.1 mm (±3.2767 m), rotation vector rx, ry, rz in mrad (±32.767 rad).
inline constexpr double kPositionScale = 1e4;  // register units per metre
inline constexpr double kRotationScale = 1e3;  // register units per radian

// Holding registers: command block (edge -> robot).
namespace cmd {
inline constexpr int kCommand = 0;    // Command
inline constexpr int kSequence = 1;   // u16; a command runs when this changes
inline constexpr int kHeartbeat = 2;  // u16; the edge changes it at least every heartbeat period
inline constexpr int kSprayMs = 3;    // u16, spray duration in ms (Command::kSpray)
inline constexpr int kTarget = 4;  // 6 registers: pose of 'tool' in 'base' (kPositionScale, kRotationScale)
inline constexpr int kSpeed = 10;  // f32, 2 registers: tool speed limit in m/s; 0 = robot's maximum
inline constexpr int kCount = 12;
}  // namespace cmd

// Input registers: status block (robot -> edge).
namespace status {
inline constexpr int kSequence = 0;      // u16, last command the robot accepted (or rejected)
inline constexpr int kState = 1;         // State
inline constexpr int kFaults = 2;        // u16, Fault bits
inline constexpr int kHeartbeat = 3;     // u16, echo of the last heartbeat seen
inline constexpr int kToolPose = 4;      // 6 registers, current tool pose (same encoding as cmd::kTarget)
inline constexpr int kSprayCount = 10;   // u32, sprays done since power-up
inline constexpr int kRobotTimeMs = 12;  // u32, robot's clock in ms (wraps after ~49.7 days)
inline constexpr int kToolSpeed = 14;    // f32, current tool tip speed in m/s
inline constexpr int kCount = 16;
}  // namespace status

enum class Command : std::uint16_t {
  kIdle = 0,   // nothing to do; with a new sequence it clears latched faults
  kMove = 1,   // move the tool to the target pose (straight line, bounded speed and acceleration)
  kSpray = 2,  // open the sprayer for cmd::kSprayMs where the tool is
  kAbort = 3,  // stop now, sprayer off
};

enum class State : std::uint16_t {
  kIdle = 0,      // ready; the command with status::kSequence has finished
  kMoving = 1,    // executing a move
  kSpraying = 2,  // sprayer open
  kFault = 3,     // the command with status::kSequence was rejected; see kFaults
  kStopped = 4,   // stopped by abort or heartbeat loss; sprayer off
};

namespace fault {
inline constexpr std::uint16_t kWorkspace = 1u << 0;      // target outside the workspace limits
inline constexpr std::uint16_t kHeartbeatLost = 1u << 1;  // heartbeat stale: motion and sprayer stopped
inline constexpr std::uint16_t kBadCommand = 1u << 2;     // unknown command word or bad parameter
inline constexpr std::uint16_t kAborted = 1u << 3;        // stopped by Command::kAbort
inline constexpr std::uint16_t kDrive = 1u << 4;          // the robot's own fault (drive, collision): stopped
// Stops the station causes itself (heartbeat pause between jobs, its own abort, a
// refused command): a reset clears them. The others need the robot's operator.
inline constexpr std::uint16_t kClearableByStation = kHeartbeatLost | kAborted | kWorkspace | kBadCommand;
}  // namespace fault

const char* to_string(Command c);
const char* to_string(State s);
// "workspace|heartbeat_lost" etc.; "none" for 0.
std::string fault_names(std::uint16_t faults);

// Pose <-> 6 registers (cmd::kTarget / status::kToolPose). encode throws EncodingError
// naming the axis when a coordinate does not fit.
void encode_pose(const Transform& T_base_tool, std::span<std::uint16_t> regs);
Transform decode_pose(std::span<const std::uint16_t> regs);

}  // namespace dentmark::robot_link
