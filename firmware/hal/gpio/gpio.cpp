#include "dentmark/firmware/hal/gpio/gpio.h"

namespace dentmark::hal {

GpioLines request_board_lines(Gpio& gpio, const board::GpioConfig& config) {
  GpioLines lines;
  // The valve first, closed: it must never be left floating while the rest is set up.
  lines.sprayer_valve = gpio.request_output(config.sprayer_valve, false);
  lines.estop = gpio.request_input(config.estop);
  if (!config.part_present.name.empty()) lines.part_present = gpio.request_input(config.part_present);
  return lines;
}

}  // namespace dentmark::hal
