#pragma once
// Replay protection for authenticated frames (docs/protocol.md, "Replay window").
// A frame is accepted when its send_time lies within ±window of the receiver's clock
// and its sequence number has not been accepted before within that window. Senders
// start their sequence at a random 62-bit value and count up, so several senders
// never collide in practice. The HMAC covers both fields, so they cannot be altered.

#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>

namespace dentmark::protocol {

class ReplayGuard {
 public:
  enum class Verdict { kAccepted, kStale, kReplayed, kFull };

  // window: s; capacity bounds the memory of remembered sequence numbers.
  explicit ReplayGuard(double window = 30.0, std::size_t capacity = 65536);

  // 'now' is the receiver's time (s since the Unix epoch) from the injected clock.
  // Thread-safe. Remembers the sequence when it returns kAccepted.
  Verdict check(std::uint64_t sequence, double send_time, double now);

  double window() const { return window_; }

 private:
  double window_;
  std::size_t capacity_;
  std::mutex mutex_;
  std::map<std::uint64_t, double> seen_;  // sequence -> send_time
};

const char* to_string(ReplayGuard::Verdict v);

}  // namespace dentmark::protocol
