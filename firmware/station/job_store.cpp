#include "dentmark/firmware/station/job_store.h"

#include <algorithm>
#include <cstdio>
#include <sstream>

#include "dentmark/common/log.h"
#include "dentmark/common/protocol/dml_file.h"

namespace dentmark::station {
namespace fs = std::filesystem;

namespace {

const char* state_name(protocol::EdgeState s) {
  return s == protocol::EdgeState::kSafe ? "safe" : "done";
}

std::string mark_line(const protocol::Mark& m) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "mark %u %u %u %.17g %.17g %.17g %.17g %.17g", m.defect_id,
                static_cast<unsigned>(m.outcome), static_cast<unsigned>(m.reason), m.time,
                m.tool_position.x(), m.tool_position.y(), m.tool_position.z(), m.estimated_error);
  return buf;
}

// One journal line into 'job'; false when the line is malformed.
bool apply_line(const std::string& line, StoredJob& job) {
  std::istringstream in(line);
  std::string kind;
  in >> kind;
  if (kind == "spray") {
    std::uint32_t id = 0;
    if (!(in >> id)) return false;
    job.spray_started.insert(id);
  } else if (kind == "mark") {
    protocol::Mark m;
    unsigned outcome = 0, reason = 0;
    double x = 0, y = 0, z = 0;
    if (!(in >> m.defect_id >> outcome >> reason >> m.time >> x >> y >> z >> m.estimated_error)) return false;
    if (outcome > 2 || reason > 7) return false;
    m.outcome = static_cast<protocol::MarkOutcome>(outcome);
    m.reason = static_cast<protocol::MarkReason>(reason);
    m.tool_position = {x, y, z};
    job.marks.push_back(m);
  } else if (kind == "end") {
    std::string state;
    if (!(in >> state) || (state != "done" && state != "safe")) return false;
    job.end = state == "safe" ? protocol::EdgeState::kSafe : protocol::EdgeState::kDone;
  } else {
    return false;
  }
  std::string rest;
  return !(in >> rest);
}

}  // namespace

bool StoredJob::reported(std::uint32_t defect_id) const {
  return std::any_of(marks.begin(), marks.end(),
                     [&](const protocol::Mark& m) { return m.defect_id == defect_id; });
}

void JobJournal::spraying(std::uint32_t defect_id) {
  log_.append("spray " + std::to_string(defect_id));
}

void JobJournal::reported(const protocol::Mark& mark) {
  log_.append(mark_line(mark));
}

void JobJournal::end(protocol::EdgeState state) {
  log_.append(std::string("end ") + state_name(state));
}

JobStore::JobStore(fs::path state_dir, std::size_t keep) : dir_(std::move(state_dir)), keep_(keep) {
  std::error_code ec;
  fs::create_directories(dir_ / "jobs", ec);
  if (ec) throw JobStoreError(dir_.string() + ": cannot create the state directory: " + ec.message());
}

fs::path JobStore::job_dir(std::uint64_t job_id) const {
  return dir_ / "jobs" / std::to_string(job_id);
}

void JobStore::store(std::span<const std::uint8_t> frame, const protocol::DefectList& list) {
  const fs::path d = job_dir(list.job_id);
  std::error_code ec;
  fs::remove_all(d, ec);  // a list never run (refused or replaced) leaves nothing behind
  fs::create_directories(d, ec);
  if (ec) throw JobStoreError(d.string() + ": cannot create: " + ec.message());
  try {
    files::write_atomically(d / "list.dml", frame);
  } catch (const files::FileError& e) {
    throw JobStoreError(e.what());
  }
  prune();
}

std::unique_ptr<JobJournal> JobStore::journal(std::uint64_t job_id) const {
  try {
    return std::make_unique<JobJournal>(job_dir(job_id) / "journal");
  } catch (const files::FileError& e) {
    throw JobStoreError(e.what());
  }
}

StoredJob JobStore::load_job(const fs::path& d) const {
  StoredJob job;
  const auto frame = protocol::read_frame_file((d / "list.dml").string());
  auto decoded = protocol::decode(frame, protocol::DecodeOptions{});
  if (!decoded || !std::holds_alternative<protocol::DefectList>(decoded.value().message))
    throw JobStoreError((d / "list.dml").string() + ": not a DefectList");
  job.list = std::get<protocol::DefectList>(decoded.value().message);
  job.digest = protocol::payload_digest(frame);
  const fs::path jp = d / "journal";
  if (!fs::exists(jp)) return job;
  const std::string text = files::read_all(jp);
  std::size_t start = 0;
  int line_no = 0;
  while (start < text.size()) {
    const std::size_t nl = text.find('\n', start);
    ++line_no;
    if (nl == std::string::npos) break;  // torn last line: the step it recorded never went on
    const std::string line = text.substr(start, nl - start);
    start = nl + 1;
    if (!apply_line(line, job))
      throw JobStoreError(jp.string() + ":" + std::to_string(line_no) + ": malformed journal line '" + line +
                          "'");
  }
  return job;
}

std::vector<StoredJob> JobStore::load() const {
  std::vector<std::pair<fs::file_time_type, fs::path>> dirs;
  for (const auto& e : fs::directory_iterator(dir_ / "jobs")) {
    if (!e.is_directory() || !fs::exists(e.path() / "list.dml")) continue;
    dirs.emplace_back(fs::last_write_time(e.path() / "list.dml"), e.path());
  }
  std::sort(dirs.begin(), dirs.end());
  std::vector<StoredJob> jobs;
  for (const auto& [when, d] : dirs) jobs.push_back(load_job(d));
  return jobs;
}

std::vector<StoredJob> JobStore::recover(double now_unix) const {
  std::vector<StoredJob> ended;
  for (StoredJob& job : load()) {
    if (job.end) continue;
    auto j = journal(job.list.job_id);
    int aborted = 0;
    for (const protocol::Defect& d : job.list.defects) {
      if (job.reported(d.id)) continue;
      protocol::Mark m;
      m.defect_id = d.id;
      m.outcome = protocol::MarkOutcome::kFailed;
      m.reason = protocol::MarkReason::kAborted;
      m.time = now_unix;
      j->reported(m);
      job.marks.push_back(m);
      ++aborted;
    }
    j->end(protocol::EdgeState::kSafe);
    job.end = protocol::EdgeState::kSafe;
    log::warn("job " + std::to_string(job.list.job_id) + " was interrupted: " + std::to_string(aborted) +
              " defects reported failed/aborted (" + std::to_string(job.spray_started.size()) +
              " had reached the valve and are never sprayed again)");
    ended.push_back(std::move(job));
  }
  return ended;
}

void JobStore::prune() const {
  std::vector<std::pair<fs::file_time_type, fs::path>> dirs;
  for (const auto& e : fs::directory_iterator(dir_ / "jobs"))
    if (e.is_directory()) dirs.emplace_back(fs::last_write_time(e.path()), e.path());
  if (dirs.size() <= keep_) return;
  std::sort(dirs.begin(), dirs.end());
  std::error_code ec;
  for (std::size_t i = 0; i + keep_ < dirs.size(); ++i) fs::remove_all(dirs[i].second, ec);
}

}  // namespace dentmark::station
