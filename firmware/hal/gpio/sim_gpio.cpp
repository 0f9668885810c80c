#include "dentmark/firmware/hal/gpio/sim_gpio.h"

#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

namespace dentmark::hal {

// A line request: it acts on its line only while it holds it (release_all() ends
// every request at once, as the kernel does for a killed process).
class SimOutputLine final : public OutputLine {
 public:
  SimOutputLine(SimGpio& chip, std::string name, SimGpio::Line& line)
      : chip_(chip), name_(std::move(name)), line_(line), request_(line.request.load()) {}
  ~SimOutputLine() override {
    std::lock_guard<std::mutex> lock(chip_.mutex_);
    if (held()) line_.requested = false;
  }
  void set(bool active) override {
    std::lock_guard<std::mutex> lock(chip_.mutex_);
    if (held() && line_.active.exchange(active) != active) chip_.record(name_, active, chip_.clock_.now());
  }
  bool get() const override { return line_.active.load(); }
  void force_inactive() noexcept override {
    if (held() && line_.active.exchange(false))
      SimGpio::record_signal_safe(chip_.record_fd_, name_.c_str(), false);
  }
  const std::string& name() const override { return name_; }

 private:
  bool held() const noexcept { return line_.request.load() == request_; }
  SimGpio& chip_;
  std::string name_;
  SimGpio::Line& line_;
  const std::uint64_t request_;
};

class SimInputLine final : public InputLine {
 public:
  SimInputLine(SimGpio& chip, std::string name, SimGpio::Line& line)
      : chip_(chip), name_(std::move(name)), line_(line), request_(line.request.load()) {}
  ~SimInputLine() override {
    std::lock_guard<std::mutex> lock(chip_.mutex_);
    if (!held()) return;
    line_.requested = false;
    line_.events.clear();
  }
  bool get() override { return line_.active.load(); }
  std::optional<LineEvent> wait_event(double timeout) override {
    std::unique_lock<std::mutex> lock(chip_.mutex_);
    // On the chip's clock: in the twin the e-stop edge is seen at the simulated instant
    // it is driven.
    // One wait: it may end early (callers poll), and on a manual clock it ends after the
    // timeout in real time instead of waiting for time that nobody moves.
    if (line_.events.empty() || !held())
      chip_.clock_.wait_until(lock, chip_.changed_, chip_.clock_.now() + std::max(0.0, timeout));
    if (line_.events.empty() || !held()) return std::nullopt;
    const LineEvent e = line_.events.front();
    line_.events.pop_front();
    return e;
  }
  const std::string& name() const override { return name_; }

 private:
  bool held() const noexcept { return line_.request.load() == request_; }
  SimGpio& chip_;
  std::string name_;
  SimGpio::Line& line_;
  const std::uint64_t request_;
};

SimGpio::SimGpio(std::vector<std::string> lines, clock::Clock& clock, const std::string& record_path)
    : clock_(clock) {
  for (auto& n : lines) lines_[n];
  if (!record_path.empty()) {
    record_fd_ = ::open(record_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (record_fd_ < 0) throw GpioError(record_path + ": cannot open GPIO record: " + std::strerror(errno));
  }
}

SimGpio::~SimGpio() {
  if (record_fd_ >= 0) ::close(record_fd_);
}

SimGpio::Line& SimGpio::find(const std::string& name) {
  const auto it = lines_.find(name);
  if (it == lines_.end()) throw GpioError("gpio line '" + name + "' not found on the simulated chip");
  return it->second;
}

std::unique_ptr<OutputLine> SimGpio::request_output(const board::GpioLine& line, bool initial_active) {
  std::lock_guard<std::mutex> lock(mutex_);
  Line& l = find(line.name);
  if (l.requested) throw GpioError("gpio line '" + line.name + "' is busy (already requested)");
  l.requested = true;
  ++l.request;
  l.output = true;
  // Recorded even when unchanged: the moment the line starts being driven matters.
  l.active.store(initial_active);
  record(line.name, initial_active, clock_.now());
  return std::make_unique<SimOutputLine>(*this, line.name, l);
}

std::unique_ptr<InputLine> SimGpio::request_input(const board::GpioLine& line) {
  std::lock_guard<std::mutex> lock(mutex_);
  Line& l = find(line.name);
  if (l.requested) throw GpioError("gpio line '" + line.name + "' is busy (already requested)");
  l.requested = true;
  ++l.request;
  l.output = false;
  l.events.clear();
  return std::make_unique<SimInputLine>(*this, line.name, l);
}

void SimGpio::drive(const std::string& name, bool active) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    Line& l = find(name);
    if (l.output) throw GpioError("gpio line '" + name + "' is an output: drive() is for inputs");
    if (l.active.exchange(active) == active) return;
    const double now = clock_.now();
    record(name, active, now);
    if (l.requested) l.events.push_back({active, now});
  }
  clock_.notify_all(changed_);
}

void SimGpio::release_all() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& [name, l] : lines_) {
      if (!l.requested) continue;
      l.requested = false;
      ++l.request;
      l.events.clear();
      if (l.output && l.active.exchange(false)) record(name, false, clock_.now());
    }
  }
  clock_.notify_all(changed_);
}

bool SimGpio::level(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = lines_.find(name);
  if (it == lines_.end()) throw GpioError("gpio line '" + name + "' not found on the simulated chip");
  return it->second.active.load();
}

std::vector<EdgeRecord> SimGpio::edges() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return edges_;
}

// mutex_ held.
void SimGpio::record(const std::string& name, bool active, double time) {
  edges_.push_back({time, name, active});
  if (record_fd_ < 0) return;
  std::ostringstream os;
  os << static_cast<long long>(std::llround(time * 1e9)) << " " << name << " " << (active ? 1 : 0) << "\n";
  const std::string s = os.str();
  [[maybe_unused]] const ssize_t n = ::write(record_fd_, s.data(), s.size());
}

void SimGpio::record_signal_safe(int fd, const char* name, bool active) noexcept {
  if (fd < 0) return;
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  unsigned long long ns = static_cast<unsigned long long>(ts.tv_sec) * 1000000000ull + ts.tv_nsec;
  // Formatted by hand: snprintf is not async-signal-safe.
  char buf[160];
  char digits[24];
  int nd = 0;
  do {
    digits[nd++] = static_cast<char>('0' + ns % 10);
    ns /= 10;
  } while (ns && nd < 24);
  std::size_t len = 0;
  while (nd > 0) buf[len++] = digits[--nd];
  buf[len++] = ' ';
  for (const char* p = name; *p && len < sizeof buf - 4; ++p) buf[len++] = *p;
  buf[len++] = ' ';
  buf[len++] = active ? '1' : '0';
  buf[len++] = '\n';
  [[maybe_unused]] const ssize_t n = ::write(fd, buf, len);
}

std::vector<EdgeRecord> SimGpio::read_record(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw GpioError(path + ": cannot open GPIO record");
  std::vector<EdgeRecord> out;
  std::string text;
  int lineno = 0;
  while (std::getline(in, text)) {
    ++lineno;
    std::istringstream is(text);
    long long ns = 0;
    EdgeRecord r;
    int v = -1;
    if (!(is >> ns >> r.line >> v) || (v != 0 && v != 1))
      throw GpioError(path + ":" + std::to_string(lineno) + ": expected '<ns> <line> <0|1>', got '" + text +
                      "'");
    r.time = ns * 1e-9;
    r.active = v == 1;
    out.push_back(r);
  }
  return out;
}

}  // namespace dentmark::hal
