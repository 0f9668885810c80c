#pragma once
// The host's side of one job (docs/protocol.md §8), shared by `dentmark send --wait`,
// `dentmark status` and the station's twin: send the DefectList and check its Ack,
// then subscribe to the job's reports and collect one outcome per defect, reconnecting
// and subscribing again (the edge resends what it has) when the connection drops.

#include <chrono>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

#include "dentmark/common/protocol/link_client.h"

namespace dentmark::protocol {

// The edge answered with an Error (it refused the request).
class Refused : public std::runtime_error {
 public:
  explicit Refused(ErrorMessage error);
  const ErrorMessage& error() const { return error_; }

 private:
  ErrorMessage error_;
};

struct SentJob {
  Ack ack;
  bool ack_matches = false;  // job, count, sequence and payload digest are the ones sent
  bool authenticated = false;
};

struct JobWaitOptions {
  double timeout = 600.0;  // s for the whole job
  double silence = 5.0;    // s without any frame (heartbeats come every second) before reconnecting
  std::function<void(const Mark&)> on_mark;      // each new outcome
  std::function<void(const Status&)> on_status;  // each heartbeat
};

struct JobOutcome {
  std::map<std::uint32_t, Mark> marks;  // by defect id
  std::optional<Status> last_status;
  bool complete = false;  // every defect of the list has an outcome
  int reconnects = 0;
};

class JobSession {
 public:
  explicit JobSession(ClientOptions options) : client_(std::move(options)) {}
  // Throws LinkError (no answer) or Refused (an Error came back).
  SentJob send(const DefectList& list);
  // Collects the list's outcomes until every defect has one or the timeout runs out.
  // Throws Refused when the edge does not know the job.
  JobOutcome wait(const DefectList& list, const JobWaitOptions& options);
  // The edge's Status. Throws LinkError or Refused.
  Status status();

 private:
  LinkClient client_;
};

// True when every dent, bump and hole of the list was marked.
bool all_marked(const DefectList& list, const JobOutcome& outcome);

}  // namespace dentmark::protocol
