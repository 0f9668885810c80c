#pragma once
// Simulated GPIO: a set of named lines like a gpio-sim chip. Outputs record every
// edge (line, level, time) in memory and, optionally, to a file with one write(2)
// per edge, so a test can read what a process did even after it was killed.
// Tests drive the inputs with drive().
//
// Record file lines: "<time in ns> <line name> <0|1>\n". Edges written from a signal
// handler (force_inactive) carry CLOCK_MONOTONIC time, since a simulated clock takes
// a lock; others carry the injected clock's time.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <vector>

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/hal/gpio/gpio.h"

namespace dentmark::hal {

struct EdgeRecord {
  double time = 0.0;
  std::string line;
  bool active = false;
};

class SimGpio final : public Gpio {
 public:
  // 'lines': the names this chip has. record_path: empty for memory only.
  SimGpio(std::vector<std::string> lines, clock::Clock& clock, const std::string& record_path = "");
  ~SimGpio() override;

  std::unique_ptr<OutputLine> request_output(const board::GpioLine& line, bool initial_active) override;
  std::unique_ptr<InputLine> request_input(const board::GpioLine& line) override;

  // Test side: sets an input's logical level; an edge wakes its waiters.
  void drive(const std::string& line, bool active);
  // Current logical level of any line.
  bool level(const std::string& line) const;
  std::vector<EdgeRecord> edges() const;
  // Ends every request at once, as the kernel does when the process holding the lines
  // dies: an output falls back to inactive (a released line follows its pull, and the
  // valve is wired to close unpowered), and the old handles no longer act on the lines.
  void release_all();

  // Parses a record file; throws GpioError naming file and line on bad content.
  static std::vector<EdgeRecord> read_record(const std::string& path);

 private:
  friend class SimOutputLine;
  friend class SimInputLine;
  struct Line {
    bool requested = false;
    std::atomic<std::uint64_t> request{0};  // which request holds the line (handles compare)
    bool output = false;
    std::atomic<bool> active{false};  // atomic: force_inactive() changes it without the lock
    std::deque<LineEvent> events;
  };
  Line& find(const std::string& name);
  void record(const std::string& name, bool active, double time);
  static void record_signal_safe(int fd, const char* name, bool active) noexcept;

  clock::Clock& clock_;
  int record_fd_ = -1;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::string, Line> lines_;
  std::vector<EdgeRecord> edges_;
};

}  // namespace dentmark::hal
