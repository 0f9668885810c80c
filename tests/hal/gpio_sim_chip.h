#pragma once
// A gpio-sim chip made through configfs (Documentation/admin-guide/gpio/gpio-sim.rst,
// Linux 6.1): one device with one bank of named lines, live while this object lives.
// The lines' simulated inputs are driven through the chip's sysfs 'pull' attribute
// and their levels (outputs as the consumer drives them) read through 'value':
// /sys/bus/gpio/devices/<chip_name>/sim_gpio<offset>/{pull,value}.
// Needs root and the gpio-sim module; the QEMU system-test guest has both.

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace dentmark::test {

class GpioSimChip {
 public:
  static constexpr const char* kConfigfs = "/sys/kernel/config/gpio-sim";

  static bool available() { return std::filesystem::is_directory(kConfigfs); }

  // Creates device 'device_name' whose bank has 'label' and one line per name.
  GpioSimChip(const std::string& device_name, const std::string& label, const std::vector<std::string>& lines)
      : dev_(std::filesystem::path(kConfigfs) / device_name), lines_(lines) {
    make_dir(dev_);
    make_dir(dev_ / "bank0");
    write(dev_ / "bank0" / "label", label);
    write(dev_ / "bank0" / "num_lines", std::to_string(lines.size()));
    for (std::size_t i = 0; i < lines.size(); ++i) {
      make_dir(line_dir(i));
      write(line_dir(i) / "name", lines[i]);
    }
    write(dev_ / "live", "1");
    chip_name_ = read(dev_ / "bank0" / "chip_name");
  }
  ~GpioSimChip() {
    std::error_code ec;
    std::ofstream(dev_ / "live") << "0";
    for (std::size_t i = 0; i < lines_.size(); ++i) std::filesystem::remove(line_dir(i), ec);
    std::filesystem::remove(dev_ / "bank0", ec);
    std::filesystem::remove(dev_, ec);
  }
  GpioSimChip(const GpioSimChip&) = delete;
  GpioSimChip& operator=(const GpioSimChip&) = delete;

  // The gpiochip the kernel made ("gpiochip1").
  const std::string& chip_name() const { return chip_name_; }

  // sysfs attribute 'attr' ("pull" or "value") of the line called 'line'.
  std::filesystem::path attribute(const std::string& line, const std::string& attr) const {
    for (std::size_t i = 0; i < lines_.size(); ++i)
      if (lines_[i] == line)
        return std::filesystem::path("/sys/bus/gpio/devices") / chip_name_ /
               ("sim_gpio" + std::to_string(i)) / attr;
    throw std::runtime_error("gpio-sim: no line '" + line + "' on " + chip_name_);
  }
  // Pulls the simulated input up (physical level 1) or down (0).
  void pull(const std::string& line, bool up) const {
    write(attribute(line, "pull"), up ? "pull-up" : "pull-down");
  }

  static void write(const std::filesystem::path& path, const std::string& text) {
    std::ofstream f(path);
    f << text;
    f.close();
    if (!f) throw std::runtime_error("gpio-sim: cannot write '" + text + "' to " + path.string());
  }
  static std::string read(const std::filesystem::path& path) {
    std::ifstream f(path);
    std::string s;
    if (!std::getline(f, s)) throw std::runtime_error("gpio-sim: cannot read " + path.string());
    return s;
  }

 private:
  std::filesystem::path line_dir(std::size_t i) const {
    return dev_ / "bank0" / ("line" + std::to_string(i));
  }
  static void make_dir(const std::filesystem::path& p) {
    std::error_code ec;
    if (!std::filesystem::create_directory(p, ec) || ec)
      throw std::runtime_error("gpio-sim: cannot create " + p.string() + ": " +
                               (ec ? ec.message() : std::string("exists")));
  }

  std::filesystem::path dev_;
  std::vector<std::string> lines_;
  std::string chip_name_;
};

}  // namespace dentmark::test
