#include "dentmark/firmware/station/station_link.h"

#include <string>

namespace dentmark::station {
namespace {

protocol::ErrorMessage unsupported(const protocol::Decoded& d, std::uint64_t job_id,
                                   const std::string& text) {
  protocol::ErrorMessage e;
  e.code = protocol::ErrorCode::kUnsupported;
  e.job_id = job_id;
  e.offending_sequence = d.header.sequence;
  e.text = text.substr(0, protocol::wire::kMaxStringLength);
  return e;
}

}  // namespace

link::Handler link_handler(Station& station, clock::Clock& clock) {
  return [&station, &clock](const protocol::Decoded& d, std::span<const std::uint8_t> frame) -> link::Reply {
    if (std::holds_alternative<protocol::DefectList>(d.message)) return station.accept(d, frame, clock.now());
    if (std::holds_alternative<protocol::Status>(d.message)) return station.status();
    if (const auto* request = std::get_if<protocol::MarkReport>(&d.message)) {
      if (!request->marks.empty())
        return unsupported(d, request->job_id,
                           "a MarkReport sent to the edge must have no records (subscription)");
      auto so_far = station.reports(request->job_id);
      if (!so_far)
        return unsupported(d, request->job_id, "job " + std::to_string(request->job_id) + " is unknown");
      const std::uint64_t job = request->job_id;
      const std::size_t sent = so_far->marks.size();
      return link::Reply(std::move(*so_far),
                         [&station, job, sent](const link::Push& push) { station.follow(job, sent, push); });
    }
    return unsupported(
        d, 0, std::string("the edge does not take ") + protocol::to_string(d.header.type) + " frames");
  };
}

}  // namespace dentmark::station
