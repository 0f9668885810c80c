#include "dentmark/firmware/link/job_inbox.h"

#include <string>

#include "dentmark/common/log.h"

namespace dentmark::link {

protocol::Message JobInbox::handle(const protocol::Decoded& decoded, std::span<const std::uint8_t> frame,
                                   double now) {
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

std::optional<Job> JobInbox::last_job() const {
  std::lock_guard lock(mutex_);
  return last_;
}

std::uint64_t JobInbox::jobs_received() const {
  std::lock_guard lock(mutex_);
  return count_;
}

}  // namespace dentmark::link
