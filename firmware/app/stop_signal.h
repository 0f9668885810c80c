#pragma once
// SIGINT/SIGTERM as a file descriptor (signalfd): the daemon's loops poll it with
// their other descriptors, so a stop request is handled in normal control flow and
// every exit path runs the same shutdown (sprayer off, robot stopped).

#include <chrono>

namespace dentmark::edge {

class StopSignal {
 public:
  // Blocks SIGINT and SIGTERM for the calling thread (create before starting threads,
  // so they inherit the mask) and opens the signalfd.
  StopSignal();
  ~StopSignal();
  StopSignal(const StopSignal&) = delete;
  StopSignal& operator=(const StopSignal&) = delete;

  int fd() const { return fd_; }
  // Waits up to 'timeout' for a stop signal; returns true once one has arrived.
  bool wait_for(std::chrono::milliseconds timeout);
  bool requested() const { return signal_ != 0; }
  int signal_number() const { return signal_; }

 private:
  int fd_ = -1;
  int signal_ = 0;
};

}  // namespace dentmark::edge
