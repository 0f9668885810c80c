#include "dentmark/common/protocol/job_session.h"

#include <thread>

namespace dentmark::protocol {
namespace {

using Seconds = std::chrono::duration<double>;

std::chrono::milliseconds ms(double seconds) {
  return std::chrono::milliseconds(static_cast<long>(seconds * 1000.0));
}

}  // namespace

Refused::Refused(ErrorMessage error)
    : std::runtime_error(std::string(to_string(error.code)) + ": " + error.text), error_(std::move(error)) {}

SentJob JobSession::send(const DefectList& list) {
  const Decoded reply = client_.request(list);
  if (const auto* e = std::get_if<ErrorMessage>(&reply.message)) throw Refused(*e);
  const auto* ack = std::get_if<Ack>(&reply.message);
  if (ack == nullptr) throw LinkError(std::string("unexpected reply ") + to_string(reply.header.type));
  SentJob s;
  s.ack = *ack;
  s.authenticated = reply.authenticated;
  s.ack_matches = ack->digest == client_.last_digest() && ack->count == list.defects.size() &&
                  ack->job_id == list.job_id && ack->acked_sequence == client_.last_sequence();
  return s;
}

Status JobSession::status() {
  const Decoded reply = client_.request(Status{});
  if (const auto* e = std::get_if<ErrorMessage>(&reply.message)) throw Refused(*e);
  const auto* s = std::get_if<Status>(&reply.message);
  if (s == nullptr) throw LinkError(std::string("unexpected reply ") + to_string(reply.header.type));
  return *s;
}

JobOutcome JobSession::wait(const DefectList& list, const JobWaitOptions& o) {
  JobOutcome out;
  const auto deadline = std::chrono::steady_clock::now() + Seconds(o.timeout);
  const auto take = [&](const MarkReport& r) {
    for (const Mark& m : r.marks) {
      if (r.job_id != list.job_id || out.marks.count(m.defect_id)) continue;  // a resend after reconnecting
      out.marks[m.defect_id] = m;
      if (o.on_mark) o.on_mark(m);
    }
    out.complete = out.marks.size() >= list.defects.size();
  };
  bool first = true;
  while (!out.complete && std::chrono::steady_clock::now() < deadline) {
    if (!first) {
      ++out.reconnects;
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
    first = false;
    try {
      const Decoded reply = client_.request(MarkReport{list.job_id, {}});
      if (const auto* e = std::get_if<ErrorMessage>(&reply.message)) throw Refused(*e);
      const auto* so_far = std::get_if<MarkReport>(&reply.message);
      if (so_far == nullptr) throw LinkError(std::string("unexpected reply ") + to_string(reply.header.type));
      take(*so_far);
      while (!out.complete) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0) break;
        auto d = client_.receive(std::min(left, ms(o.silence)));
        if (!d) break;  // silent edge: reconnect and subscribe again
        if (const auto* e = std::get_if<ErrorMessage>(&d->message)) throw Refused(*e);
        if (const auto* r = std::get_if<MarkReport>(&d->message)) take(*r);
        if (const auto* s = std::get_if<Status>(&d->message)) {
          out.last_status = *s;
          if (o.on_status) o.on_status(*s);
        }
      }
    } catch (const LinkError&) {
      // The edge restarted or the network dropped: its store keeps the outcomes.
    }
  }
  return out;
}

bool all_marked(const DefectList& list, const JobOutcome& outcome) {
  for (const Defect& d : list.defects) {
    if (d.defect_class != DefectClass::kDent && d.defect_class != DefectClass::kBump &&
        d.defect_class != DefectClass::kHole)
      continue;
    const auto it = outcome.marks.find(d.id);
    if (it == outcome.marks.end() || it->second.outcome != MarkOutcome::kMarked) return false;
  }
  return true;
}

}  // namespace dentmark::protocol
