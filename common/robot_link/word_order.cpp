#include "dentmark/common/robot_link/word_order.h"

#include <bit>
#include <cmath>
#include <sstream>

namespace dentmark::robot_link {
namespace {

void need_two(std::size_t size) {
  if (size < 2) throw EncodingError("a 32-bit register value needs 2 registers, got " + std::to_string(size));
}

}  // namespace

void put_u32(std::span<std::uint16_t> regs, std::uint32_t v, WordOrder order) {
  need_two(regs.size());
  const auto hi = static_cast<std::uint16_t>(v >> 16);
  const auto lo = static_cast<std::uint16_t>(v & 0xFFFFu);
  regs[0] = order == WordOrder::kHighWordFirst ? hi : lo;
  regs[1] = order == WordOrder::kHighWordFirst ? lo : hi;
}

std::uint32_t get_u32(std::span<const std::uint16_t> regs, WordOrder order) {
  need_two(regs.size());
  const std::uint32_t hi = order == WordOrder::kHighWordFirst ? regs[0] : regs[1];
  const std::uint32_t lo = order == WordOrder::kHighWordFirst ? regs[1] : regs[0];
  return (hi << 16) | lo;
}

void put_i32(std::span<std::uint16_t> regs, std::int32_t v, WordOrder order) {
  put_u32(regs, static_cast<std::uint32_t>(v), order);
}

std::int32_t get_i32(std::span<const std::uint16_t> regs, WordOrder order) {
  return static_cast<std::int32_t>(get_u32(regs, order));
}

void put_f32(std::span<std::uint16_t> regs, float v, WordOrder order) {
  put_u32(regs, std::bit_cast<std::uint32_t>(v), order);
}

float get_f32(std::span<const std::uint16_t> regs, WordOrder order) {
  return std::bit_cast<float>(get_u32(regs, order));
}

std::uint16_t encode_scaled_i16(double value, double scale, const char* what) {
  const double scaled = std::round(value * scale);
  if (!std::isfinite(scaled) || scaled < -32768.0 || scaled > 32767.0) {
    std::ostringstream os;
    os << what << ": " << value << " does not fit a signed 16-bit register at scale " << scale << " (range "
       << -32768.0 / scale << " .. " << 32767.0 / scale << ")";
    throw EncodingError(os.str());
  }
  return encode_i16(static_cast<std::int16_t>(scaled));
}

}  // namespace dentmark::robot_link
