// The daemon's job store: what it writes before an Ack and before a spray, and what it
// makes of an interrupted job after a restart (SIGKILL, power cut).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "dentmark/common/protocol/codec.h"
#include "dentmark/firmware/station/job_store.h"

namespace dentmark::station {
namespace {
namespace fs = std::filesystem;
using protocol::MarkOutcome;
using protocol::MarkReason;

protocol::DefectList three_defects(std::uint64_t job) {
  protocol::DefectList l;
  l.job_id = job;
  l.panel_id = "door";
  l.scan_time = 1.75e9;
  for (std::uint32_t id = 1; id <= 3; ++id) {
    protocol::Defect d;
    d.id = id;
    d.position = Eigen::Vector3d(0.1 * id, 0, 0);
    l.defects.push_back(d);
  }
  return l;
}

std::vector<std::uint8_t> frame_of(const protocol::DefectList& l) {
  protocol::EncodeOptions eo;
  eo.sequence = 7;
  eo.send_time = 1.75e9 + 1;
  return protocol::encode(l, eo);
}

class JobStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           ("jobstore-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

protocol::Mark marked(std::uint32_t id) {
  protocol::Mark m;
  m.defect_id = id;
  m.time = 1.75e9 + 10.25;
  m.tool_position = Eigen::Vector3d(0.1, -0.2, 0.30000000000000004);
  m.estimated_error = 4.5e-4;
  return m;
}

TEST_F(JobStoreTest, JournalRoundTripsEveryFieldExactly) {
  JobStore store(dir_);
  const auto list = three_defects(5);
  const auto frame = frame_of(list);
  store.store(frame, list);
  {
    auto j = store.journal(5);
    j->spraying(1);
    j->reported(marked(1));
    protocol::Mark skipped;
    skipped.defect_id = 2;
    skipped.outcome = MarkOutcome::kSkipped;
    skipped.reason = MarkReason::kOutOfReach;
    j->reported(skipped);
    j->end(protocol::EdgeState::kDone);
  }
  const auto jobs = store.load();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].list, list);
  EXPECT_EQ(jobs[0].digest, protocol::payload_digest(frame));
  ASSERT_EQ(jobs[0].marks.size(), 2u);
  EXPECT_EQ(jobs[0].marks[0], marked(1));  // %.17g: every bit of every double
  EXPECT_EQ(jobs[0].marks[1].reason, MarkReason::kOutOfReach);
  EXPECT_EQ(jobs[0].spray_started, std::set<std::uint32_t>{1});
  EXPECT_EQ(jobs[0].end, protocol::EdgeState::kDone);
  EXPECT_TRUE(store.recover(0.0).empty()) << "a finished job is not recovered";
}

TEST_F(JobStoreTest, InterruptedJobReportsTheRestAbortedAndNeverSpraysAgain) {
  {
    JobStore store(dir_);
    const auto list = three_defects(9);
    store.store(frame_of(list), list);
    auto j = store.journal(9);
    j->spraying(1);
    j->reported(marked(1));
    j->spraying(2);  // the daemon died with the valve open on defect 2
  }
  JobStore after(dir_);
  const auto ended = after.recover(1.75e9 + 99);
  ASSERT_EQ(ended.size(), 1u);
  const StoredJob& job = ended[0];
  ASSERT_EQ(job.marks.size(), 3u);
  EXPECT_EQ(job.marks[0].outcome, MarkOutcome::kMarked);
  for (int i = 1; i < 3; ++i) {
    EXPECT_EQ(job.marks[i].outcome, MarkOutcome::kFailed);
    EXPECT_EQ(job.marks[i].reason, MarkReason::kAborted);
    EXPECT_EQ(job.marks[i].time, 1.75e9 + 99);
  }
  EXPECT_TRUE(job.spray_started.count(2));
  EXPECT_EQ(job.end, protocol::EdgeState::kSafe);
  // On disk too: a second restart finds nothing to recover and the same outcomes.
  EXPECT_TRUE(after.recover(0.0).empty());
  const auto reloaded = JobStore(dir_).load();
  ASSERT_EQ(reloaded.size(), 1u);
  EXPECT_EQ(reloaded[0].marks, job.marks);
}

TEST_F(JobStoreTest, TornLastLineIsIgnoredAndABadLineIsNamed) {
  JobStore store(dir_);
  const auto list = three_defects(3);
  store.store(frame_of(list), list);
  store.journal(3)->reported(marked(1));
  const fs::path journal = dir_ / "jobs" / "3" / "journal";
  {
    std::ofstream out(journal, std::ios::app);
    out << "mark 2 0 0 1.0 0.1";  // power cut in the middle of a line
  }
  auto jobs = store.load();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].marks.size(), 1u);
  {
    std::ofstream out(journal, std::ios::app);
    out << "\nend done\n";  // the torn line now sits inside the file: corruption
  }
  try {
    store.load();
    FAIL() << "a malformed journal line must be refused";
  } catch (const JobStoreError& e) {
    EXPECT_NE(std::string(e.what()).find(journal.string() + ":2: malformed journal line"), std::string::npos)
        << e.what();
  }
}

TEST_F(JobStoreTest, KeepsOnlyTheNewestJobs) {
  JobStore store(dir_, 2);
  for (std::uint64_t id = 1; id <= 4; ++id) {
    const auto list = three_defects(id);
    store.store(frame_of(list), list);
    fs::last_write_time(dir_ / "jobs" / std::to_string(id),
                        fs::file_time_type::clock::now() - std::chrono::hours(10 - static_cast<int>(id)));
  }
  const auto list = three_defects(5);
  store.store(frame_of(list), list);
  int left = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "jobs")) left += e.is_directory();
  EXPECT_EQ(left, 2);
  EXPECT_TRUE(fs::exists(dir_ / "jobs" / "5"));
  EXPECT_TRUE(fs::exists(dir_ / "jobs" / "4"));
}

}  // namespace
}  // namespace dentmark::station
