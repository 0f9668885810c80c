#include "dentmark/firmware/station/station.h"

#include <algorithm>
#include <chrono>
#include <limits>

#include "dentmark/common/log.h"

namespace dentmark::station {

using protocol::EdgeState;

struct Station::JobRecord {
  protocol::DefectList list;
  protocol::Digest digest{};
  std::vector<protocol::Mark> marks;
  std::optional<EdgeState> end;
};

namespace {

constexpr double kForever = std::numeric_limits<double>::infinity();

std::string job_name(std::uint64_t id) {
  return "job " + std::to_string(id);
}

// The faults a job's outcomes point at.
std::uint32_t faults_of(const std::vector<protocol::Mark>& marks) {
  std::uint32_t f = 0;
  for (const protocol::Mark& m : marks) {
    if (m.reason == protocol::MarkReason::kRobotFault) f |= fault::kRobot;
    if (m.reason == protocol::MarkReason::kTrackingLost) f |= fault::kTracking;
    if (m.reason == protocol::MarkReason::kEmergencyStop) f |= fault::kEstop;
  }
  return f;
}

}  // namespace

Station::Station(StationDevices devices, JobStore& store, StationConfig config)
    : dev_(std::move(devices)), store_(store), config_(std::move(config)), started_at_(dev_.clock.now()) {}

Station::~Station() {
  stop();
}

void Station::start() {
  for (const StoredJob& j : store_.recover(dev_.unix_time())) {
    if (j.spray_started.empty()) continue;
    log::warn(job_name(j.list.job_id) +
              ": defects that reached the valve before the restart are reported, "
              "never sprayed again");
  }
  {
    std::lock_guard lock(mutex_);
    for (StoredJob& j : store_.load()) {
      auto r = std::make_shared<JobRecord>();
      r->list = std::move(j.list);
      r->digest = j.digest;
      r->marks = std::move(j.marks);
      r->end = j.end;
      current_job_ = r->list.job_id;
      if (r->end == EdgeState::kSafe) job_faults_ = faults_of(r->marks);
      state_ = r->end.value_or(EdgeState::kIdle) == EdgeState::kSafe ? EdgeState::kSafe : EdgeState::kIdle;
      jobs_[r->list.job_id] = std::move(r);
    }
    stopping_ = false;
  }
  dev_.safety.valve_off();
  thread_ = clock::ParticipantThread(dev_.clock, [this] { job_loop(); });
}

void Station::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    if (runner_) runner_->cancel();
  }
  dev_.clock.notify_all(changed_);
  if (thread_.joinable()) thread_.join();
  dev_.safety.valve_off();
}

protocol::ErrorMessage Station::refusal(const protocol::Decoded& d, protocol::ErrorCode code,
                                        const std::string& text) const {
  protocol::ErrorMessage e;
  e.code = code;
  e.offending_sequence = d.header.sequence;
  if (const auto* l = std::get_if<protocol::DefectList>(&d.message)) e.job_id = l->job_id;
  e.text = text.substr(0, protocol::wire::kMaxStringLength);
  for (char& ch : e.text)
    if (ch < 0x20 || ch > 0x7E) ch = '?';
  log::warn(std::string("link: refused ") + protocol::to_string(d.header.type) + ": " + e.text);
  return e;
}

protocol::Message Station::accept(const protocol::Decoded& d, std::span<const std::uint8_t> frame,
                                  double received) {
  const auto* list = std::get_if<protocol::DefectList>(&d.message);
  if (list == nullptr) return refusal(d, protocol::ErrorCode::kUnsupported, "not a DefectList");
  protocol::Ack ack;
  ack.job_id = list->job_id;
  ack.acked_sequence = d.header.sequence;
  ack.count = static_cast<std::uint32_t>(list->defects.size());
  ack.digest = protocol::payload_digest(frame);

  std::unique_lock lock(mutex_);
  if (const auto it = jobs_.find(list->job_id); it != jobs_.end()) {
    // A resend (the host retried, or reconnected after our restart): same content is
    // acknowledged and never run again; other content under a used id is refused.
    if (it->second->digest == ack.digest) return ack;
    return refusal(d, protocol::ErrorCode::kBusy,
                   job_name(list->job_id) + " was already received with other content; use a new job id");
  }
  if (busy_ || pending_)
    return refusal(d, protocol::ErrorCode::kBusy, job_name(current_job_) + " is running; wait for it to end");
  if (stopping_) return refusal(d, protocol::ErrorCode::kBusy, "the daemon is stopping");
  const std::uint32_t device_faults = dev_.extra_faults ? dev_.extra_faults() : 0;
  if (device_faults & fault::kCalibration)
    return refusal(d, protocol::ErrorCode::kInternal,
                   "the stored calibration is known bad; recalibrate (dentmark-edge calibrate verify)");
  if (auto why = dev_.tracking.refuse(*list)) return refusal(d, protocol::ErrorCode::kUnsupported, *why);
  // The line as it reads now: after an e-stop is released, the next job clears its latch (arm()).
  if (dev_.safety.estop_pressed()) return refusal(d, protocol::ErrorCode::kBusy, "e-stop is pressed");
  try {
    store_.store(frame, *list);
  } catch (const JobStoreError& e) {
    return refusal(d, protocol::ErrorCode::kInternal, std::string("cannot store the job: ") + e.what());
  }
  auto r = std::make_shared<JobRecord>();
  r->list = *list;
  r->digest = ack.digest;
  jobs_[list->job_id] = r;
  // The scan's age when the host sent the list, on the host's own clock, taken back
  // from the arrival on ours (see the header).
  const double age = d.header.send_time - list->scan_time;
  if (age < 0)
    log::warn(job_name(list->job_id) + ": scan_time lies after the frame's send_time; taken as now");
  pending_ = Pending{*list, received - std::max(0.0, age)};
  current_job_ = list->job_id;
  state_ = EdgeState::kJobReceived;
  lock.unlock();
  dev_.clock.notify_all(changed_);
  log::info(job_name(list->job_id) + " panel '" + list->panel_id +
            "': " + std::to_string(list->defects.size()) + " defects accepted; scan " +
            std::to_string(std::max(0.0, age)) + " s before sending" +
            (d.authenticated ? " (authenticated)" : ""));
  return ack;
}

protocol::Status Station::status() const {
  protocol::Status s;
  s.protocol_major = protocol::wire::kMajor;
  s.protocol_minor = protocol::wire::kMinor;
  s.firmware_version = config_.firmware_version;
  s.uptime = std::max(0.0, dev_.clock.now() - started_at_);
  std::uint32_t faults = dev_.tracking.faults() | (dev_.extra_faults ? dev_.extra_faults() : 0);
  if (dev_.safety.estop_active()) faults |= fault::kEstop;
  std::lock_guard lock(mutex_);
  s.state = state_;
  s.job_id = current_job_;
  s.fault_bits = faults | (state_ == EdgeState::kSafe ? job_faults_ : 0);
  if (const auto it = jobs_.find(current_job_); it != jobs_.end()) {
    s.defects_total = static_cast<std::uint32_t>(it->second->list.defects.size());
    s.defects_reported = static_cast<std::uint32_t>(it->second->marks.size());
  }
  return s;
}

std::optional<protocol::MarkReport> Station::reports(std::uint64_t job_id) const {
  std::lock_guard lock(mutex_);
  const auto it = jobs_.find(job_id);
  if (it == jobs_.end()) return std::nullopt;
  return protocol::MarkReport{job_id, it->second->marks};
}

void Station::follow(std::uint64_t job_id, std::size_t already_sent, const PushMessage& push) {
  std::size_t sent = already_sent;
  double next_beat = dev_.clock.now() + config_.heartbeat_period;
  for (;;) {
    protocol::MarkReport fresh{job_id, {}};
    bool ended = false;
    {
      std::unique_lock lock(mutex_);
      const auto it = jobs_.find(job_id);
      if (it == jobs_.end()) return;
      const JobRecord& job = *it->second;
      if (!(stopping_ || job.marks.size() > sent || job.end.has_value()))
        dev_.clock.wait_until(lock, changed_, next_beat);
      if (stopping_) return;
      fresh.marks.assign(job.marks.begin() + static_cast<std::ptrdiff_t>(std::min(sent, job.marks.size())),
                         job.marks.end());
      ended = job.end.has_value();
    }
    if (!fresh.marks.empty()) {
      if (!push(fresh)) return;
      sent += fresh.marks.size();
    }
    if (ended) {
      push(status());
      return;
    }
    if (dev_.clock.now() >= next_beat) {
      if (!push(status())) return;
      next_beat = dev_.clock.now() + config_.heartbeat_period;
    }
  }
}

bool Station::wait_idle(double timeout) {
  const double deadline = dev_.clock.now() + timeout;
  std::unique_lock lock(mutex_);
  while (busy_ || pending_) {
    if (dev_.clock.now() >= deadline) return false;
    changed_.wait_for(lock, std::chrono::milliseconds(20));
  }
  return true;
}

void Station::record(std::uint64_t job_id, const protocol::Mark& mark) {
  {
    std::lock_guard lock(mutex_);
    if (const auto it = jobs_.find(job_id); it != jobs_.end()) it->second->marks.push_back(mark);
  }
  dev_.clock.notify_all(changed_);
}

void Station::finish(std::uint64_t job_id, EdgeState end, std::uint32_t faults) {
  // Before the end is visible: whoever sees the job ended sees the hook's effect too.
  if (config_.on_job_end) config_.on_job_end(job_id);
  {
    std::lock_guard lock(mutex_);
    if (const auto it = jobs_.find(job_id); it != jobs_.end()) it->second->end = end;
    state_ = end;
    job_faults_ = faults;
    busy_ = false;
  }
  dev_.clock.notify_all(changed_);
}

void Station::job_loop() {
  for (;;) {
    Pending job;
    {
      std::unique_lock lock(mutex_);
      while (!stopping_ && !pending_) dev_.clock.wait_until(lock, changed_, kForever);
      if (stopping_ && !pending_) return;
      job = std::move(*pending_);
      pending_.reset();
      busy_ = true;
    }
    run_job(job);
  }
}

// Journals each event before passing it on to the in-memory record (the host's view).
class RecordingEvents final : public JobEvents {
 public:
  RecordingEvents(JobJournal& journal, std::function<void(const protocol::Mark&)> on_mark)
      : journal_(journal), on_mark_(std::move(on_mark)) {}
  void spraying(std::uint32_t id) override { journal_.spraying(id); }
  void reported(const protocol::Mark& m) override {
    journal_.reported(m);
    on_mark_(m);
  }

 private:
  JobJournal& journal_;
  std::function<void(const protocol::Mark&)> on_mark_;
};

bool Station::wait_for_part(std::uint64_t job_id) {
  if (!dev_.part_present) return true;
  const double deadline = dev_.clock.now() + config_.part_timeout;
  while (!dev_.part_present()) {
    dev_.safety.kick();
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return false;
    }
    if (dev_.safety.estop_active() || dev_.clock.now() >= deadline) {
      log::warn(
          job_name(job_id) + ": " +
          (dev_.safety.estop_active() ? "e-stop while waiting for the panel" : "the panel did not arrive"));
      return false;
    }
    dev_.clock.sleep_for(config_.job.poll_period);
  }
  return true;
}

void Station::run_job(const Pending& job) {
  const std::uint64_t id = job.list.job_id;
  // On a simulated clock the job's own work (planning, Modbus round trips) takes no
  // time; time runs while the job waits (clock.h). Real clocks ignore this.
  dev_.clock.begin_work();
  struct EndWork {
    clock::Clock& clock;
    ~EndWork() { clock.end_work(); }
  } end_work{dev_.clock};
  std::unique_ptr<JobJournal> journal;
  try {
    journal = store_.journal(id);
  } catch (const JobStoreError& e) {
    log::error(job_name(id) + ": " + e.what() + "; job not run");
    finish(id, EdgeState::kSafe, fault::kLink);
    return;
  }
  RecordingEvents events(*journal, [this, id](const protocol::Mark& m) { record(id, m); });
  const auto give_up = [&](protocol::MarkOutcome outcome, protocol::MarkReason reason) {
    for (const protocol::Defect& d : job.list.defects) {
      protocol::Mark m;
      m.defect_id = d.id;
      m.outcome = outcome;
      m.reason = reason;
      m.time = dev_.unix_time();
      events.reported(m);
    }
  };

  std::unique_ptr<MotionSource> motion;
  try {
    motion = dev_.tracking.start(job.list, job.t_scan);
  } catch (const std::exception& e) {
    log::error(job_name(id) + ": tracking did not start: " + e.what());
    give_up(protocol::MarkOutcome::kSkipped, protocol::MarkReason::kTrackingLost);
    journal->end(EdgeState::kSafe);
    finish(id, EdgeState::kSafe, fault::kTracking);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    state_ = EdgeState::kTracking;
  }
  if (!wait_for_part(id)) {
    const bool estop = dev_.safety.estop_active();
    give_up(protocol::MarkOutcome::kFailed,
            estop ? protocol::MarkReason::kEmergencyStop : protocol::MarkReason::kTimeout);
    journal->end(EdgeState::kSafe);
    finish(id, EdgeState::kSafe, estop ? fault::kEstop : 0);
    return;
  }
  JobConfig jc = config_.job;
  jc.epoch_offset = dev_.unix_time() - dev_.clock.now();
  JobRunner runner(dev_.robot, dev_.safety, *motion, dev_.clock, jc);
  {
    std::lock_guard lock(mutex_);
    state_ = EdgeState::kMarking;
    runner_ = &runner;
    if (stopping_) runner.cancel();
  }
  const protocol::MarkReport report = runner.run(job.list, job.t_scan, &events);
  {
    std::lock_guard lock(mutex_);
    runner_ = nullptr;
  }
  const EdgeState end = runner.state() == EdgeState::kSafe ? EdgeState::kSafe : EdgeState::kDone;
  journal->end(end);
  int marked = 0;
  for (const protocol::Mark& m : report.marks) marked += m.outcome == protocol::MarkOutcome::kMarked;
  log::info(job_name(id) + " " + (end == EdgeState::kSafe ? "ended safe" : "done") + ": " +
            std::to_string(marked) + " of " + std::to_string(job.list.defects.size()) + " defects marked");
  finish(id, end, end == EdgeState::kSafe ? faults_of(report.marks) : 0);
}

}  // namespace dentmark::station
