#pragma once
// The daemon's receiving end for jobs: acknowledges each valid DefectList and keeps
// the last one as the current job (the tracker and planner take it from here).

#include <cstdint>
#include <mutex>
#include <optional>
#include <span>

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

}  // namespace dentmark::link
