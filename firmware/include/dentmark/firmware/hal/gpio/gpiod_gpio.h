#pragma once
// GPIO through the Linux character device with libgpiod's v1 API (Debian 12 ships
// 1.6). Lines are found by name, in the chip with 'chip_label' when one is given,
// else in any chip. Outputs are requested with their initial value in the same
// ioctl, so the valve never glitches open; inputs with both-edge events, whose kernel
// timestamps are on CLOCK_MONOTONIC (Linux >= 5.7).
// Kernel-level tests (gpio-sim) belong to the QEMU system-test tier.

#include <string>

#include "dentmark/firmware/hal/gpio/gpio.h"

namespace dentmark::hal {

class GpiodGpio final : public Gpio {
 public:
  // consumer: the label the kernel shows for our requests (gpioinfo).
  explicit GpiodGpio(std::string chip_label, std::string consumer = "dentmark-edge");
  std::unique_ptr<OutputLine> request_output(const board::GpioLine& line, bool initial_active) override;
  std::unique_ptr<InputLine> request_input(const board::GpioLine& line) override;

 private:
  std::string chip_label_;
  std::string consumer_;
};

}  // namespace dentmark::hal
