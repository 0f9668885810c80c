#pragma once
// GPIO lines as the edge uses them (design.md §5): the sprayer valve (output,
// requested with its safe value), the e-stop and part-present inputs (with edge
// events). Lines are found by name (board file), never by chip and offset. Values
// are logical: 'active' means valve open / e-stop pressed / part present, whatever
// the wiring's polarity (active_low in the board file).
//
// Backends: libgpiod v1 (gpiod_gpio.h, the Linux character device) and simulated
// (sim_gpio.h, which records every edge with its timestamp).

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "dentmark/firmware/board/board_config.h"

namespace dentmark::hal {

class GpioError : public std::runtime_error {
 public:
  explicit GpioError(const std::string& what) : std::runtime_error(what) {}
};

struct LineEvent {
  bool active = false;  // the logical level after the edge
  double time = 0.0;    // s, CLOCK_MONOTONIC line (kernel timestamp) or the simulated clock
};

class OutputLine {
 public:
  virtual ~OutputLine() = default;
  virtual void set(bool active) = 0;
  virtual bool get() const = 0;
  // Drives the line inactive using only async-signal-safe calls (no locks, no
  // allocation): for signal handlers and std::terminate. Never throws.
  virtual void force_inactive() noexcept = 0;
  virtual const std::string& name() const = 0;
};

class InputLine {
 public:
  virtual ~InputLine() = default;
  virtual bool get() = 0;
  // Waits up to 'timeout' real seconds for an edge; std::nullopt on timeout.
  virtual std::optional<LineEvent> wait_event(double timeout) = 0;
  virtual const std::string& name() const = 0;
};

class Gpio {
 public:
  virtual ~Gpio() = default;
  // Requests an output, driven to 'initial_active' from the first instant (the
  // request itself sets it: no glitch through another value).
  virtual std::unique_ptr<OutputLine> request_output(const board::GpioLine& line, bool initial_active) = 0;
  // Requests an input with both-edge events.
  virtual std::unique_ptr<InputLine> request_input(const board::GpioLine& line) = 0;
};

// The three lines of the board, requested: valve off, inputs with events.
struct GpioLines {
  std::unique_ptr<OutputLine> sprayer_valve;
  std::unique_ptr<InputLine> estop;
  std::unique_ptr<InputLine> part_present;  // null when the board has no part sensor
};
GpioLines request_board_lines(Gpio& gpio, const board::GpioConfig& config);

}  // namespace dentmark::hal
