#include "dentmark/firmware/hal/gpio/gpiod_gpio.h"

#include <gpiod.h>

#include <cerrno>
#include <cmath>
#include <cstring>

namespace dentmark::hal {
namespace {

// A requested line and the chip handle it came from (closing the chip releases it).
struct Handle {
  gpiod_chip* chip = nullptr;
  gpiod_line* line = nullptr;
  Handle() = default;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (line) gpiod_line_release(line);
    if (chip) gpiod_chip_close(chip);
  }
};

std::unique_ptr<Handle> find_line(const std::string& chip_label, const std::string& name) {
  auto h = std::make_unique<Handle>();
  if (!chip_label.empty()) {
    h->chip = gpiod_chip_open_by_label(chip_label.c_str());
    if (!h->chip)
      throw GpioError("gpio chip with label '" + chip_label + "' not found: " + std::strerror(errno));
    h->line = gpiod_chip_find_line(h->chip, name.c_str());
    if (!h->line) throw GpioError("gpio line '" + name + "' not found on chip '" + chip_label + "'");
  } else {
    h->line = gpiod_line_find(name.c_str());
    if (!h->line) throw GpioError("gpio line '" + name + "' not found on any chip");
    h->chip = gpiod_line_get_chip(h->line);
  }
  return h;
}

int flags_of(const board::GpioLine& line) {
  return line.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
}

class GpiodOutput final : public OutputLine {
 public:
  GpiodOutput(std::unique_ptr<Handle> h, std::string name, bool active)
      : h_(std::move(h)), name_(std::move(name)), active_(active) {}
  void set(bool active) override {
    if (gpiod_line_set_value(h_->line, active ? 1 : 0) != 0)
      throw GpioError("gpio line '" + name_ + "': set: " + std::strerror(errno));
    active_ = active;
  }
  bool get() const override { return active_; }
  // gpiod_line_set_value is one GPIOHANDLE_SET_LINE_VALUES ioctl on the request's fd,
  // with no allocation or locking: usable from a signal handler.
  void force_inactive() noexcept override {
    gpiod_line_set_value(h_->line, 0);
    active_ = false;
  }
  const std::string& name() const override { return name_; }

 private:
  std::unique_ptr<Handle> h_;
  std::string name_;
  volatile bool active_ = false;
};

class GpiodInput final : public InputLine {
 public:
  GpiodInput(std::unique_ptr<Handle> h, std::string name) : h_(std::move(h)), name_(std::move(name)) {}
  bool get() override {
    const int v = gpiod_line_get_value(h_->line);
    if (v < 0) throw GpioError("gpio line '" + name_ + "': get: " + std::strerror(errno));
    return v == 1;
  }
  std::optional<LineEvent> wait_event(double timeout) override {
    timeout = std::max(0.0, timeout);
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(timeout);
    ts.tv_nsec = static_cast<long>((timeout - std::floor(timeout)) * 1e9);
    int r;
    do {
      r = gpiod_line_event_wait(h_->line, &ts);
    } while (r < 0 && errno == EINTR);
    if (r < 0) throw GpioError("gpio line '" + name_ + "': wait: " + std::strerror(errno));
    if (r == 0) return std::nullopt;
    gpiod_line_event ev{};
    if (gpiod_line_event_read(h_->line, &ev) != 0)
      throw GpioError("gpio line '" + name_ + "': read event: " + std::strerror(errno));
    return LineEvent{ev.event_type == GPIOD_LINE_EVENT_RISING_EDGE,
                     static_cast<double>(ev.ts.tv_sec) + 1e-9 * static_cast<double>(ev.ts.tv_nsec)};
  }
  const std::string& name() const override { return name_; }

 private:
  std::unique_ptr<Handle> h_;
  std::string name_;
};

}  // namespace

GpiodGpio::GpiodGpio(std::string chip_label, std::string consumer)
    : chip_label_(std::move(chip_label)), consumer_(std::move(consumer)) {}

std::unique_ptr<OutputLine> GpiodGpio::request_output(const board::GpioLine& line, bool initial_active) {
  auto h = find_line(chip_label_, line.name);
  if (gpiod_line_request_output_flags(h->line, consumer_.c_str(), flags_of(line), initial_active ? 1 : 0) !=
      0)
    throw GpioError("gpio line '" + line.name + "': request as output: " + std::strerror(errno));
  return std::make_unique<GpiodOutput>(std::move(h), line.name, initial_active);
}

std::unique_ptr<InputLine> GpiodGpio::request_input(const board::GpioLine& line) {
  auto h = find_line(chip_label_, line.name);
  if (gpiod_line_request_both_edges_events_flags(h->line, consumer_.c_str(), flags_of(line)) != 0)
    throw GpioError("gpio line '" + line.name + "': request with edge events: " + std::strerror(errno));
  return std::make_unique<GpiodInput>(std::move(h), line.name);
}

}  // namespace dentmark::hal
