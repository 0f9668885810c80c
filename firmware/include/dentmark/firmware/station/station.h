#pragma once
// The edge daemon's state machine (design.md §4, "Daemon"): it takes jobs from the link,
// tracks each job's panel from the scan on, waits for the panel to reach the marking
// place, marks it through the job runner, and reports every defect's outcome back.
//
//   idle ──DefectList──▶ job_received ──tracking started──▶ tracking
//        (refused: busy, unknown panel model, calibration bad; nothing moves)
//   tracking ──part present (or at once without a sensor)──▶ marking ──▶ done
//   any fault (e-stop, robot, tracking lost, timeout, stop) ──▶ safe: valve closed,
//        robot aborted, every remaining defect reported with its reason.
//
// Durability: a list is written to the JobStore before it is acknowledged, and every
// outcome (and every valve opening) is journalled before the next step, so a restart
// after a crash or SIGKILL reports the interrupted job's unmarked defects failed /
// aborted and never sprays a defect twice (job_store.h). A list whose job id is
// already known with the same content is acknowledged again but never re-run.
//
// Time: the host's scan_time is mapped onto this daemon's clock by the frame that
// carried the list: t_scan = t_received − (send_time − scan_time). The host stamps
// both on its own clock, so only their difference (the scan's age when sent) crosses
// machines, and the error is the one-way network delay (about a millisecond on the
// station's network: 14 µm of line travel at 0.014 m/s). No clock synchronisation is
// needed.

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>

#include "dentmark/common/clock/clock.h"
#include "dentmark/common/protocol/codec.h"
#include "dentmark/firmware/hal/robot/robot.h"
#include "dentmark/firmware/station/job_runner.h"
#include "dentmark/firmware/station/job_store.h"
#include "dentmark/firmware/station/motion_source.h"

namespace dentmark::station {

// Status fault bits (docs/protocol.md §4.4).
namespace fault {
inline constexpr std::uint32_t kEstop = 1u << 0;
inline constexpr std::uint32_t kRobot = 1u << 1;
inline constexpr std::uint32_t kCamera = 1u << 2;
inline constexpr std::uint32_t kTracking = 1u << 3;
inline constexpr std::uint32_t kLink = 1u << 4;
inline constexpr std::uint32_t kCalibration = 1u << 5;  // protocol 1.1: stored calibration known bad
}  // namespace fault

// How the station follows a job's panel: the daemon tracks it in the cameras from a
// taught panel model; tests and the truth-motion twin plug in other sources.
class PanelTracking {
 public:
  virtual ~PanelTracking() = default;
  // Why this list's panel cannot be tracked (e.g. no taught model for its panel_id),
  // or nullopt when it can. Called before the list is acknowledged.
  virtual std::optional<std::string> refuse(const protocol::DefectList& list) = 0;
  // A motion source whose M(t) covers t_scan (clock time) onward. Throws
  // std::runtime_error when the panel cannot be acquired.
  virtual std::unique_ptr<MotionSource> start(const protocol::DefectList& list, double t_scan) = 0;
  // Device faults (fault::kCamera ...) the tracking side knows of.
  virtual std::uint32_t faults() const { return 0; }
};

struct StationConfig {
  JobConfig job;
  double part_timeout = 300.0;    // s to wait for the part-present input before giving up a job
  double heartbeat_period = 1.0;  // s between Status frames pushed to subscribers
  std::string firmware_version;   // reported in Status
  // Called on the job thread as each job ends, after its last report and before the
  // end is visible to the host (the twin holds
  // its clock there, so a run ends at the same simulated time on any machine).
  std::function<void(std::uint64_t job_id)> on_job_end;
};

// The station's hardware and surroundings, injected (daemon: hal from the board file;
// twin: the same with simulated drivers; tests: fakes).
struct StationDevices {
  hal::Robot& robot;
  SafetyIo& safety;
  clock::Clock& clock;
  PanelTracking& tracking;
  std::function<bool()> part_present;           // empty: the board has no sensor (mark at once)
  std::function<std::uint32_t()> extra_faults;  // e.g. fault::kCalibration; may be empty
  std::function<double()> unix_time;            // s since the epoch, for reports; required
};

// Sends one message to a subscriber; false when it is gone (link::Push).
using PushMessage = std::function<bool(const protocol::Message&)>;

class Station {
 public:
  Station(StationDevices devices, JobStore& store, StationConfig config);
  ~Station();
  Station(const Station&) = delete;
  Station& operator=(const Station&) = delete;

  // Ends interrupted jobs found in the store (reports kept for the host), then starts
  // the job thread. Throws JobStoreError when the store cannot be read.
  void start();
  // Cancels a running job (valve closed, robot aborted, the rest reported aborted) and
  // joins the job thread. Idempotent.
  void stop();

  // A DefectList frame, decoded: Ack when accepted (stored first), Error otherwise.
  // 'received' is the clock time the frame arrived.
  protocol::Message accept(const protocol::Decoded& decoded, std::span<const std::uint8_t> frame,
                           double received);
  protocol::Status status() const;
  // Every outcome of a job so far; nullopt for an unknown job.
  std::optional<protocol::MarkReport> reports(std::uint64_t job_id) const;
  // Pushes a job's outcomes beyond the first 'already_sent', and a Status every
  // heartbeat, until the job has ended and everything was pushed (a last Status closes
  // it) or a push fails or the station stops.
  void follow(std::uint64_t job_id, std::size_t already_sent, const PushMessage& push);
  // Waits until no job is queued or running (clock seconds); true when idle.
  bool wait_idle(double timeout);

 private:
  struct JobRecord;
  struct Pending {
    protocol::DefectList list;
    double t_scan = 0.0;
  };
  void job_loop();
  void run_job(const Pending& job);
  bool wait_for_part(std::uint64_t job_id);
  void record(std::uint64_t job_id, const protocol::Mark& mark);
  void finish(std::uint64_t job_id, protocol::EdgeState end, std::uint32_t faults);
  protocol::ErrorMessage refusal(const protocol::Decoded& d, protocol::ErrorCode code,
                                 const std::string& text) const;

  StationDevices dev_;
  JobStore& store_;
  StationConfig config_;
  const double started_at_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::uint64_t, std::shared_ptr<JobRecord>> jobs_;
  std::optional<Pending> pending_;
  std::uint64_t current_job_ = 0;  // the job being or last run
  protocol::EdgeState state_ = protocol::EdgeState::kIdle;
  std::uint32_t job_faults_ = 0;  // faults the last job ended with
  bool busy_ = false;
  bool stopping_ = false;
  JobRunner* runner_ = nullptr;      // while a job marks (for cancel)
  clock::ParticipantThread thread_;  // takes part in simulated time (clock.h)
};

}  // namespace dentmark::station
