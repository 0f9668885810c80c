#pragma once
// 16/32-bit integer and IEEE-754 float32 values in Modbus registers, with the word
// order spelled out. Modbus defines only 16-bit registers (big-endian bytes on the
// wire; libmodbus hands us host-order uint16_t), so a 32-bit value takes two
// registers and the order of its halves is a convention each device documents.
// Our register map (docs/robot-modbus.md) uses kHighWordFirst ("ABCD", mbpoll -B).
//
// Ours rather than libmodbus's modbus_set_float_*: those in Debian's 3.1.6 swap bytes
// inside each register as well, so set/get through them does not round-trip with
// the register values a robot controller reads.

#include <cstdint>
#include <span>
#include <stdexcept>

namespace dentmark::robot_link {

enum class WordOrder {
  kHighWordFirst,  // register n holds bits 31..16, register n+1 bits 15..0 ("ABCD")
  kLowWordFirst,   // register n holds bits 15..0, register n+1 bits 31..16 ("CDAB")
};

// Thrown when a value does not fit its register encoding or a span is too short.
class EncodingError : public std::range_error {
 public:
  explicit EncodingError(const std::string& what) : std::range_error(what) {}
};

// One register.
inline std::uint16_t encode_i16(std::int16_t v) {
  return static_cast<std::uint16_t>(v);
}
inline std::int16_t decode_i16(std::uint16_t r) {
  return static_cast<std::int16_t>(r);
}

// Two registers at regs[0], regs[1] (regs.size() >= 2, else EncodingError).
void put_u32(std::span<std::uint16_t> regs, std::uint32_t v, WordOrder order);
std::uint32_t get_u32(std::span<const std::uint16_t> regs, WordOrder order);
void put_i32(std::span<std::uint16_t> regs, std::int32_t v, WordOrder order);
std::int32_t get_i32(std::span<const std::uint16_t> regs, WordOrder order);
// IEEE-754 binary32 bit pattern (NaN payloads and -0 preserved).
void put_f32(std::span<std::uint16_t> regs, float v, WordOrder order);
float get_f32(std::span<const std::uint16_t> regs, WordOrder order);

// A physical value as a scaled signed 16-bit register, e.g. metres in 0.1 mm units
// (scale 1e4). Rounds to nearest; throws EncodingError naming 'what' when the value
// is not finite or the result falls outside [-32768, 32767].
std::uint16_t encode_scaled_i16(double value, double scale, const char* what);
inline double decode_scaled_i16(std::uint16_t r, double scale) {
  return decode_i16(r) / scale;
}

}  // namespace dentmark::robot_link
