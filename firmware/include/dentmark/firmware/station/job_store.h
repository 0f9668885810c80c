#pragma once
// The daemon's durable memory of jobs (design.md §4: "job kept and reported"), in its
// state directory (/var/lib/dentmark by default):
//
//   jobs/<job_id>/list.dml   the DefectList frame exactly as received, written
//                            atomically before the list is acknowledged;
//   jobs/<job_id>/journal    one line per event, each flushed to the disk before the
//                            step it records goes on:
//                              spray <defect_id>        the valve is about to open
//                              mark <defect_id> <outcome> <reason> <time> <x> <y> <z> <error>
//                              end <state>              the job finished (done | safe)
//
// "Never spray a defect twice" rests on the spray line: it is on the disk before the
// valve opens, so after a crash a defect with a spray line and no mark is reported
// failed/aborted (it may carry paint), never marked again. A job without an end line
// was interrupted: recover() reports its unmarked defects failed/aborted and ends it.
// A torn last line (power cut during the write) is ignored; any other malformed line
// is an error naming the file and line.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "dentmark/common/atomic_file.h"
#include "dentmark/common/protocol/codec.h"
#include "dentmark/firmware/station/job_runner.h"

namespace dentmark::station {

class JobStoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct StoredJob {
  protocol::DefectList list;
  protocol::Digest digest{};
  std::vector<protocol::Mark> marks;       // in the order they were decided
  std::set<std::uint32_t> spray_started;   // defects whose valve may have opened
  std::optional<protocol::EdgeState> end;  // set once the job finished

  bool reported(std::uint32_t defect_id) const;
};

// One job's journal: appends and flushes each event (JobEvents for the runner).
class JobJournal final : public JobEvents {
 public:
  explicit JobJournal(const std::filesystem::path& path) : log_(path) {}
  void spraying(std::uint32_t defect_id) override;
  void reported(const protocol::Mark& mark) override;
  void end(protocol::EdgeState state);

 private:
  files::AppendLog log_;
};

class JobStore {
 public:
  // keep: finished jobs kept on disk (the oldest beyond that are removed).
  explicit JobStore(std::filesystem::path state_dir, std::size_t keep = 32);

  // Writes the received frame before the list is acknowledged. Throws JobStoreError
  // when it cannot (the list must then be refused, not acknowledged).
  void store(std::span<const std::uint8_t> frame, const protocol::DefectList& list);
  std::unique_ptr<JobJournal> journal(std::uint64_t job_id) const;

  // Every job on disk, oldest first (by job folder modification time, then id).
  std::vector<StoredJob> load() const;
  // Ends every interrupted job: its defects without an outcome are reported failed /
  // aborted (in the journal), and it ends 'safe'. Returns the jobs it ended.
  std::vector<StoredJob> recover(double now_unix) const;

  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path job_dir(std::uint64_t job_id) const;
  StoredJob load_job(const std::filesystem::path& dir) const;
  void prune() const;

  std::filesystem::path dir_;
  std::size_t keep_;
};

}  // namespace dentmark::station
