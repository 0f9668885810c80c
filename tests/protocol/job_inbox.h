#pragma once
// A stand-in for the daemon's receiving end in the link's tests: acknowledges each
// valid DefectList and keeps the last one (the daemon's own is station::Station).

#include <cstdint>
#include <mutex>
#include <optional>
#include <span>
#include <string>

#include "dentmark/common/log.h"
#include "dentmark/common/protocol/codec.h"

namespace dentmark::link {

struct Job {
  protocol::DefectList list;
  protocol::Digest digest{};   // SHA-256 of the list's payload
  std::uint64_t sequence = 0;  // header sequence of the frame it came in
  double received_at = 0.0;    // s, receiver's clock
};

class JobInbox {
 public:
  // Reply to one decoded frame: Ack for a DefectList (the list becomes the last job),
  // an 'unsupported' Error for anything else. Thread-safe.
  protocol::Message handle(const protocol::Decoded& decoded, std::span<const std::uint8_t> frame, double now);

  std::optional<Job> last_job() const;
  std::uint64_t jobs_received() const;

 private:
  mutable std::mutex mutex_;
  std::optional<Job> last_;
  std::uint64_t count_ = 0;
};

inline protocol::Message JobInbox::handle(const protocol::Decoded& decoded,
                                          std::span<const std::uint8_t> frame, double now) {
  const auto* list = std::get_if<protocol::DefectList>(&decoded.message);
  if (list == nullptr) {
    protocol::ErrorMessage e;
    e.code = protocol::ErrorCode::kUnsupported;
    e.offending_sequence = decoded.header.sequence;
    e.text =
        std::string("the edge accepts DefectList frames, not ") + protocol::to_string(decoded.header.type);
    return e;
  }
  Job job;
  job.list = *list;
  job.digest = protocol::payload_digest(frame);
  job.sequence = decoded.header.sequence;
  job.received_at = now;
  protocol::Ack ack;
  ack.job_id = list->job_id;
  ack.acked_sequence = decoded.header.sequence;
  ack.count = static_cast<std::uint32_t>(list->defects.size());
  ack.digest = job.digest;
  log::info("job " + std::to_string(list->job_id) + " panel '" + list->panel_id +
            "': " + std::to_string(list->defects.size()) + " defects in frame '" + list->frame + "'" +
            (decoded.authenticated ? " (authenticated)" : ""));
  std::lock_guard lock(mutex_);
  last_ = std::move(job);
  ++count_;
  return ack;
}

inline std::optional<Job> JobInbox::last_job() const {
  std::lock_guard lock(mutex_);
  return last_;
}

inline std::uint64_t JobInbox::jobs_received() const {
  std::lock_guard lock(mutex_);
  return count_;
}

}  // namespace dentmark::link
