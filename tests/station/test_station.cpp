// The daemon's state machine (Station) with stand-in devices: jobs accepted only when
// stored, refused with a reason otherwise, marked, reported over the real link, and
// never sprayed twice across a restart.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include "dentmark/common/protocol/job_session.h"
#include "dentmark/firmware/link/link_server.h"
#include "dentmark/firmware/station/station.h"
#include "dentmark/firmware/station/station_link.h"
#include "station_fakes.h"

namespace dentmark::station {
namespace {
namespace fs = std::filesystem;
using protocol::MarkOutcome;
using protocol::MarkReason;
using testing::LineMotion;
using testing::MockRobot;
using testing::MockSafety;

constexpr double kEpoch = 1.75e9;

// Tracks every panel with the true line motion, except models it was told not to know.
class FakeTracking final : public PanelTracking {
 public:
  FakeTracking(clock::Clock& clock) : clock_(clock) {}
  std::optional<std::string> refuse(const protocol::DefectList& list) override {
    if (list.panel_id == "unknown-door") return "panel model 'unknown-door' is unknown";
    return std::nullopt;
  }
  std::unique_ptr<MotionSource> start(const protocol::DefectList&, double t_scan) override {
    scan_times.push_back(t_scan);
    return std::make_unique<LineMotion>(clock_, 0.014);
  }
  std::vector<double> scan_times;

 private:
  clock::Clock& clock_;
};

protocol::DefectList door_list(std::uint64_t job, const std::string& panel = "door") {
  protocol::DefectList l;
  l.job_id = job;
  l.panel_id = panel;
  l.scan_time = kEpoch;
  std::uint32_t id = 1;
  for (double x : {0.1, 0.4, -0.2}) {
    protocol::Defect d;
    d.id = id++;
    d.defect_class = protocol::DefectClass::kDent;
    d.position = Eigen::Vector3d(x, 0.05, 0.0);
    l.defects.push_back(d);
  }
  protocol::Defect handle;
  handle.id = 9;
  handle.defect_class = protocol::DefectClass::kDesignFeature;
  l.defects.push_back(handle);
  return l;
}

struct Received {
  std::vector<std::uint8_t> frame;
  protocol::Decoded decoded;
};

Received as_received(const protocol::DefectList& l, double send_time) {
  protocol::EncodeOptions eo;
  eo.sequence = 11;
  eo.send_time = send_time;
  Received r;
  r.frame = protocol::encode(l, eo);
  r.decoded = protocol::decode(r.frame, protocol::DecodeOptions{}).value();
  return r;
}

class StationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           (std::string("station-") + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    limits_.workspace_min = Eigen::Vector3d(-1, -1, -0.2);
    limits_.workspace_max = Eigen::Vector3d(1.5, 1, 1);
  }
  void TearDown() override { fs::remove_all(dir_); }

  StationConfig config() const {
    StationConfig c;
    c.job.planner.limits = limits_;
    c.job.planner.chain.standoff = 0.03;
    c.job.poll_period = 0.005;
    c.firmware_version = "test";
    return c;
  }
  StationDevices devices(MockRobot& robot, MockSafety& safety, FakeTracking& tracking,
                         std::function<bool()> part = {}) {
    return StationDevices{
        robot, safety, clock_, tracking, std::move(part), {}, [this] { return kEpoch + clock_.now(); }};
  }

  clock::SimClock clock_;  // manual: the job thread's sleeps move time, so jobs run instantly
  plan::RobotLimits limits_;
  fs::path dir_;
};

TEST_F(StationTest, AcceptsAStoredListMarksItAndReportsEveryDefect) {
  MockRobot robot(clock_, limits_);
  MockSafety safety(clock_);
  FakeTracking tracking(clock_);
  JobStore store(dir_);
  Station station(devices(robot, safety, tracking), store, config());
  station.start();
  const auto list = door_list(42);
  // Sent 2 s after the scan (host clock): the scan lies 2 s before the arrival here.
  const Received r = as_received(list, kEpoch + 2.0);
  const double arrival = clock_.now();
  const auto reply = station.accept(r.decoded, r.frame, arrival);
  const auto* ack = std::get_if<protocol::Ack>(&reply);
  ASSERT_NE(ack, nullptr);
  EXPECT_EQ(ack->digest, protocol::payload_digest(r.frame));
  EXPECT_EQ(ack->count, 4u);
  EXPECT_TRUE(fs::exists(dir_ / "jobs" / "42" / "list.dml")) << "stored before the Ack";
  ASSERT_TRUE(station.wait_idle(60.0));
  ASSERT_EQ(tracking.scan_times.size(), 1u);
  EXPECT_DOUBLE_EQ(tracking.scan_times[0], arrival - 2.0);

  const auto reports = station.reports(42);
  ASSERT_TRUE(reports);
  ASSERT_EQ(reports->marks.size(), 4u);
  int marked = 0;
  for (const auto& m : reports->marks) {
    if (m.defect_id == 9) {
      EXPECT_EQ(m.reason, MarkReason::kNotMarkable);
      continue;
    }
    EXPECT_EQ(m.outcome, MarkOutcome::kMarked);
    EXPECT_GT(m.time, kEpoch) << "report times are Unix times";
    ++marked;
  }
  EXPECT_EQ(marked, 3);
  EXPECT_EQ(robot.sprays.size(), 3u);
  EXPECT_FALSE(safety.valve_open);
  const protocol::Status s = station.status();
  EXPECT_EQ(s.state, protocol::EdgeState::kDone);
  EXPECT_EQ(s.job_id, 42u);
  EXPECT_EQ(s.defects_total, 4u);
  EXPECT_EQ(s.defects_reported, 4u);
  EXPECT_EQ(s.fault_bits, 0u);

  // The same list again (a host retrying): acknowledged, never run again.
  const Received again = as_received(list, kEpoch + 5.0);
  EXPECT_TRUE(
      std::holds_alternative<protocol::Ack>(station.accept(again.decoded, again.frame, clock_.now())));
  ASSERT_TRUE(station.wait_idle(10.0));
  EXPECT_EQ(robot.sprays.size(), 3u);
  // Other content under the same id: refused.
  auto changed = list;
  changed.defects.pop_back();
  const Received other = as_received(changed, kEpoch + 6.0);
  const auto refused = station.accept(other.decoded, other.frame, clock_.now());
  ASSERT_TRUE(std::holds_alternative<protocol::ErrorMessage>(refused));
  EXPECT_EQ(std::get<protocol::ErrorMessage>(refused).code, protocol::ErrorCode::kBusy);
}

TEST_F(StationTest, RefusesAnUnknownPanelModelAndMovesNothing) {
  MockRobot robot(clock_, limits_);
  MockSafety safety(clock_);
  FakeTracking tracking(clock_);
  JobStore store(dir_);
  Station station(devices(robot, safety, tracking), store, config());
  station.start();
  const Received r = as_received(door_list(7, "unknown-door"), kEpoch);
  const auto reply = station.accept(r.decoded, r.frame, clock_.now());
  const auto* err = std::get_if<protocol::ErrorMessage>(&reply);
  ASSERT_NE(err, nullptr);
  EXPECT_EQ(err->code, protocol::ErrorCode::kUnsupported);
  EXPECT_NE(err->text.find("unknown-door"), std::string::npos) << err->text;
  EXPECT_EQ(err->job_id, 7u);
  EXPECT_FALSE(fs::exists(dir_ / "jobs" / "7"));
  EXPECT_TRUE(station.wait_idle(1.0));
  EXPECT_TRUE(robot.sprays.empty());
  EXPECT_TRUE(tracking.scan_times.empty());
  EXPECT_EQ(station.status().state, protocol::EdgeState::kIdle);
}

TEST_F(StationTest, EstopPressedRefusesTheJob) {
  MockRobot robot(clock_, limits_);
  MockSafety safety(clock_);
  safety.estop_after = 0.0;
  FakeTracking tracking(clock_);
  JobStore store(dir_);
  Station station(devices(robot, safety, tracking), store, config());
  station.start();
  const Received r = as_received(door_list(8), kEpoch);
  const auto reply = station.accept(r.decoded, r.frame, clock_.now());
  ASSERT_TRUE(std::holds_alternative<protocol::ErrorMessage>(reply));
  EXPECT_NE(std::get<protocol::ErrorMessage>(reply).text.find("e-stop"), std::string::npos);
  EXPECT_EQ(station.status().fault_bits & fault::kEstop, fault::kEstop);
}

TEST_F(StationTest, WaitsForThePartBeforeMarking) {
  MockRobot robot(clock_, limits_);
  MockSafety safety(clock_);
  FakeTracking tracking(clock_);
  JobStore store(dir_);
  Station station(devices(robot, safety, tracking, [this] { return clock_.now() >= 20.0; }), store, config());
  station.start();
  const Received r = as_received(door_list(12), kEpoch);
  ASSERT_TRUE(std::holds_alternative<protocol::Ack>(station.accept(r.decoded, r.frame, clock_.now())));
  ASSERT_TRUE(station.wait_idle(60.0));
  ASSERT_EQ(robot.sprays.size(), 3u);
  for (const auto& s : robot.sprays) EXPECT_GE(s.t, 20.0) << "no spray before the part is present";
}

TEST_F(StationTest, AfterACrashTheInterruptedJobIsReportedAndNothingIsSprayedTwice) {
  const auto list = door_list(77);
  const Received r = as_received(list, kEpoch);
  {
    // What a daemon killed with the valve open on defect 2 leaves behind.
    JobStore crashed(dir_);
    crashed.store(r.frame, list);
    auto j = crashed.journal(77);
    j->spraying(1);
    protocol::Mark m;
    m.defect_id = 1;
    m.time = kEpoch + 3;
    j->reported(m);
    j->spraying(2);
  }
  MockRobot robot(clock_, limits_);
  MockSafety safety(clock_);
  FakeTracking tracking(clock_);
  JobStore store(dir_);
  Station station(devices(robot, safety, tracking), store, config());
  station.start();
  EXPECT_EQ(station.status().state, protocol::EdgeState::kSafe);
  const auto reports = station.reports(77);
  ASSERT_TRUE(reports);
  ASSERT_EQ(reports->marks.size(), 4u);
  EXPECT_EQ(reports->marks[0].outcome, MarkOutcome::kMarked);
  for (std::size_t i = 1; i < 4; ++i) {
    EXPECT_EQ(reports->marks[i].outcome, MarkOutcome::kFailed);
    EXPECT_EQ(reports->marks[i].reason, MarkReason::kAborted);
  }
  // The host resends the list after the restart: acknowledged, not run.
  EXPECT_TRUE(std::holds_alternative<protocol::Ack>(station.accept(r.decoded, r.frame, clock_.now())));
  ASSERT_TRUE(station.wait_idle(5.0));
  EXPECT_TRUE(robot.sprays.empty());
  EXPECT_EQ(safety.pulses, 0);
  // The station takes the next job.
  const Received next = as_received(door_list(78), kEpoch);
  EXPECT_TRUE(std::holds_alternative<protocol::Ack>(station.accept(next.decoded, next.frame, clock_.now())));
  ASSERT_TRUE(station.wait_idle(60.0));
  EXPECT_EQ(robot.sprays.size(), 3u);
}

TEST_F(StationTest, HostGetsEveryReportOverTheLinkAndStatusOnRequest) {
  MockRobot robot(clock_, limits_);
  MockSafety safety(clock_);
  FakeTracking tracking(clock_);
  JobStore store(dir_);
  Station station(devices(robot, safety, tracking), store, config());
  station.start();
  link::ServerOptions so;
  so.bind_address = "127.0.0.1";
  so.port = 0;
  link::LinkServer server(so, link_handler(station, clock_));
  server.start();

  protocol::ClientOptions co;
  co.port = server.port();
  protocol::JobSession host(co);
  auto list = door_list(5);
  // Scanned a second ago on this host's clock (the link stamps send_time from it).
  list.scan_time =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count() - 1.0;
  const protocol::SentJob sent = host.send(list);
  EXPECT_TRUE(sent.ack_matches);
  protocol::JobWaitOptions wo;
  wo.timeout = 60.0;
  const protocol::JobOutcome outcome = host.wait(list, wo);
  EXPECT_TRUE(outcome.complete);
  ASSERT_EQ(outcome.marks.size(), 4u);
  EXPECT_TRUE(protocol::all_marked(list, outcome));
  const auto kept = station.reports(5);
  ASSERT_TRUE(kept);
  for (const auto& m : kept->marks) EXPECT_EQ(outcome.marks.at(m.defect_id), m);

  const protocol::Status s = protocol::JobSession(co).status();
  EXPECT_EQ(s.job_id, 5u);
  EXPECT_EQ(s.defects_reported, 4u);
  EXPECT_EQ(s.protocol_minor, protocol::wire::kMinor);
  // A subscription to a job the edge does not know is refused.
  protocol::JobSession stranger(co);
  EXPECT_THROW(stranger.wait(door_list(999), wo), protocol::Refused);
  server.stop();
}

}  // namespace
}  // namespace dentmark::station
