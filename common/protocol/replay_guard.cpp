#include "dentmark/common/protocol/replay_guard.h"

#include <cmath>

namespace dentmark::protocol {

ReplayGuard::ReplayGuard(double window, std::size_t capacity) : window_(window), capacity_(capacity) {}

ReplayGuard::Verdict ReplayGuard::check(std::uint64_t sequence, double send_time, double now) {
  if (!std::isfinite(send_time) || std::abs(send_time - now) > window_) return Verdict::kStale;
  std::lock_guard lock(mutex_);
  // Forget what can no longer be replayed: older than the window is refused as stale.
  for (auto it = seen_.begin(); it != seen_.end();) {
    if (it->second < now - window_)
      it = seen_.erase(it);
    else
      ++it;
  }
  if (seen_.count(sequence) != 0) return Verdict::kReplayed;
  if (seen_.size() >= capacity_) return Verdict::kFull;
  seen_.emplace(sequence, send_time);
  return Verdict::kAccepted;
}

const char* to_string(ReplayGuard::Verdict v) {
  switch (v) {
    case ReplayGuard::Verdict::kAccepted:
      return "accepted";
    case ReplayGuard::Verdict::kStale:
      return "send_time outside the replay window";
    case ReplayGuard::Verdict::kReplayed:
      return "sequence number already seen (replay)";
    case ReplayGuard::Verdict::kFull:
      return "too many frames within the replay window";
  }
  return "?";
}

}  // namespace dentmark::protocol
