// Watches the sprayer valve's gpio-sim line from outside the edge daemon, in the
// system-test guest (docs/system-tests.md). gpio-sim shows the level a consumer drives
// on an output line in sysfs (/sys/devices/platform/gpio-sim.N/gpiochipM/sim_gpioK/
// value); this program polls it through a kept file descriptor.
//
//   valve_probe watch VALUE OUT
//     Records every pulse of the line (active high) until SIGTERM or SIGINT: one line
//     per pulse in OUT, "pulse <rise s> <fall s> <length ms>" on CLOCK_MONOTONIC, and a
//     summary on stdout. Polls every 0.5 ms.
//   valve_probe estop VALUE PULL PRESSED TIMEOUT
//     Waits up to TIMEOUT s for the valve to open, then writes PRESSED ("pull-down" or
//     "pull-up") to the e-stop line's PULL attribute and polls the valve until it reads
//     low. Prints "estop: valve low <ms> ms after the pull write" (from just before the
//     write, so the write's own time counts against the daemon), the pulse's length so
//     far, and the longest interval between two polls (how long the probe itself did not
//     run). Exit 0 measured, 1 the valve never opened or stayed open 1 s.
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

volatile sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

class Line {
 public:
  explicit Line(const std::string& path) : path_(path), fd_(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {
    if (fd_ < 0) throw std::runtime_error("cannot open " + path);
  }
  ~Line() { ::close(fd_); }
  bool high() const {
    char c = 0;
    if (::pread(fd_, &c, 1, 0) != 1) throw std::runtime_error("cannot read " + path_);
    return c == '1';
  }

 private:
  std::string path_;
  int fd_;
};

void pause_us(int us) {
  std::this_thread::sleep_for(std::chrono::microseconds(us));
}

int watch(const std::string& value, const std::string& out_path) {
  const Line valve(value);
  FILE* out = std::fopen(out_path.c_str(), "w");
  if (!out) throw std::runtime_error("cannot write " + out_path);
  std::vector<double> lengths;
  bool was = valve.high();
  double rise = was ? now() : 0.0;
  double last = now(), longest_gap = 0.0;
  while (!g_stop) {
    const bool is = valve.high();
    const double t = now();
    longest_gap = std::max(longest_gap, t - last);
    last = t;
    if (is && !was) rise = t;
    if (!is && was) {
      lengths.push_back(t - rise);
      std::fprintf(out, "pulse %.6f %.6f %.3f\n", rise, t, 1e3 * (t - rise));
      std::fflush(out);
    }
    was = is;
    pause_us(500);
  }
  if (was) std::fprintf(out, "open %.6f\n", rise);
  std::fclose(out);
  std::printf("valve_probe: %zu pulses%s; longest interval between polls %.1f ms\n", lengths.size(),
              was ? ", and the valve open at the end" : "", 1e3 * longest_gap);
  return 0;
}

int estop(const std::string& value, const std::string& pull, const std::string& pressed, double timeout) {
  const Line valve(value);
  const int pull_fd = ::open(pull.c_str(), O_WRONLY | O_CLOEXEC);
  if (pull_fd < 0) throw std::runtime_error("cannot open " + pull);
  const double begin = now();
  double rise = 0.0;
  while (!valve.high()) {
    if (g_stop || now() - begin > timeout) {
      std::printf("estop: the valve did not open (%s after %.1f s)\n", g_stop ? "stopped" : "timed out",
                  now() - begin);
      return 1;
    }
    pause_us(200);
  }
  rise = now();
  const double t0 = now();
  if (::write(pull_fd, pressed.data(), pressed.size()) != static_cast<ssize_t>(pressed.size()))
    throw std::runtime_error("cannot write '" + pressed + "' to " + pull);
  ::close(pull_fd);
  double last = now(), longest_gap = 0.0, t1 = 0.0;
  for (;;) {
    const bool open = valve.high();
    const double t = now();
    longest_gap = std::max(longest_gap, t - last);
    last = t;
    if (!open) {
      t1 = t;
      break;
    }
    if (t - t0 > 1.0) {
      std::printf("estop: the valve was still open 1 s after the e-stop\n");
      return 1;
    }
    pause_us(100);
  }
  std::printf(
      "estop: valve low %.3f ms after the pull write (valve opened %.1f ms before it); longest "
      "interval between polls %.3f ms\n",
      1e3 * (t1 - t0), 1e3 * (t0 - rise), 1e3 * longest_gap);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  const std::string mode = argc > 1 ? argv[1] : "";
  try {
    if (mode == "watch" && argc == 4) return watch(argv[2], argv[3]);
    if (mode == "estop" && argc == 6) return estop(argv[2], argv[3], argv[4], std::atof(argv[5]));
  } catch (const std::exception& e) {
    std::printf("valve_probe: %s\n", e.what());
    return 1;
  }
  std::fprintf(
      stderr,
      "usage: valve_probe watch VALUE OUT | valve_probe estop VALUE PULL pull-down|pull-up TIMEOUT\n");
  return 2;
}
