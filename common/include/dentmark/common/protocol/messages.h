#pragma once
// Host <-> edge messages (design.md §6). Plain data in SI units; the byte encoding
// lives in the codec (docs/protocol.md). Positions and normals are in the frame the
// DefectList names (the scan's frame, 'sls', for lists from `dentmark detect`).

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

namespace dentmark::protocol {

enum class DefectClass : std::uint8_t {
  kDent = 0,           // depression
  kBump = 1,           // protrusion: outward ding, weld spatter
  kHole = 2,           // missing surface
  kDesignFeature = 3,  // handle, character line, edge, window opening: never marked
  kNoise = 4,          // rejected candidate
};

struct Defect {
  std::uint32_t id = 0;
  DefectClass defect_class = DefectClass::kDent;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m, centre of the defect
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();   // unit, out of the surface (30 × 30 mm plane fit)
  double diameter = 0.0;                               // m
  double height = 0.0;                                 // m, signed: negative = depression
  double area = 0.0;                                   // m²
  double score = 0.0;                                  // confidence in [0, 1]

  bool operator==(const Defect&) const = default;
};

struct DefectList {
  std::uint64_t job_id = 0;
  std::string panel_id;
  double scan_time = 0.0;     // s since the Unix epoch (UTC) when the scan was taken
  std::string frame = "sls";  // frame of positions and normals
  std::vector<Defect> defects;

  bool operator==(const DefectList&) const = default;
};

// SHA-256 of a DefectList frame's payload bytes: the Ack proves which list arrived.
using Digest = std::array<std::uint8_t, 32>;

// Edge -> host: a DefectList arrived intact and was accepted as the current job.
struct Ack {
  std::uint64_t job_id = 0;
  std::uint64_t acked_sequence = 0;  // header sequence number of the acknowledged frame
  std::uint32_t count = 0;           // defects in the acknowledged list
  Digest digest{};                   // SHA-256 of the acknowledged list's payload

  bool operator==(const Ack&) const = default;
};

enum class MarkOutcome : std::uint8_t { kMarked = 0, kSkipped = 1, kFailed = 2 };

// Why a defect was skipped or failed (kNone when marked).
enum class MarkReason : std::uint8_t {
  kNone = 0,
  kNotMarkable = 1,    // class never marked (design feature, noise)
  kOutOfReach = 2,     // predicted pose outside the workspace limits
  kTrackingLost = 3,   // too few features / quality too low
  kRobotFault = 4,     // Modbus error, watchdog, robot reported a fault
  kEmergencyStop = 5,  // e-stop input active
  kTimeout = 6,        // a step did not finish within its time limit
  kAborted = 7,        // job cancelled or daemon stopped
};

struct Mark {
  std::uint32_t defect_id = 0;
  MarkOutcome outcome = MarkOutcome::kMarked;
  MarkReason reason = MarkReason::kNone;
  double time = 0.0;                                        // s since the Unix epoch when the sprayer fired
  Eigen::Vector3d tool_position = Eigen::Vector3d::Zero();  // m, tool tip in 'base'
  double estimated_error = 0.0;                             // m, estimated marking error (1-sigma norm)

  bool operator==(const Mark&) const = default;
};

// Edge -> host: what was marked for one job, where and when. Host -> edge (minor 1), a
// MarkReport without records subscribes to that job's reports (docs/protocol.md §8).
struct MarkReport {
  std::uint64_t job_id = 0;
  std::vector<Mark> marks;

  bool operator==(const MarkReport&) const = default;
};

enum class EdgeState : std::uint8_t {
  kIdle = 0,
  kJobReceived = 1,
  kTracking = 2,
  kMarking = 3,
  kDone = 4,
  kSafe = 5
};

// Edge -> host heartbeat. Host -> edge (minor 1), any Status frame asks for the edge's.
struct Status {
  EdgeState state = EdgeState::kIdle;
  std::uint32_t fault_bits = 0;  // see docs/protocol.md (bit 0 e-stop, 1 robot, 2 camera, 3 tracking, 4 link)
  std::uint64_t job_id = 0;      // current or last job, 0 when none
  std::string firmware_version;  // e.g. "0.1.0"
  std::uint8_t protocol_major = 0;
  std::uint8_t protocol_minor = 0;
  double uptime = 0.0;  // s since the daemon started
  // Since minor 1 (0 in frames of minor 0): defects in the current or last job, and how
  // many of them have a MarkReport record so far.
  std::uint32_t defects_total = 0;
  std::uint32_t defects_reported = 0;

  bool operator==(const Status&) const = default;
};

enum class ErrorCode : std::uint16_t {
  kMalformedFrame = 1,   // the peer's frame failed to decode (detail says why)
  kUnauthenticated = 2,  // unsigned frame, bad HMAC or replay while a key is configured
  kUnsupported = 3,      // message type not accepted in this direction
  kBusy = 4,             // a job is running and cannot be replaced
  kInternal = 5,
};

// Either side: a request was refused.
struct ErrorMessage {
  ErrorCode code = ErrorCode::kInternal;
  std::uint64_t job_id = 0;              // job concerned, 0 when unknown
  std::uint64_t offending_sequence = 0;  // sequence of the refused frame, 0 when unknown
  std::uint32_t byte_offset = 0;         // where decoding failed, 0 when not a decode error
  std::string text;                      // one line, printable ASCII, ≤ 255 bytes

  bool operator==(const ErrorMessage&) const = default;
};

using Message = std::variant<DefectList, Ack, MarkReport, Status, ErrorMessage>;

}  // namespace dentmark::protocol
