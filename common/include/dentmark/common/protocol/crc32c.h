#pragma once
// CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), the frame trailer.

#include <cstdint>
#include <span>

namespace dentmark::protocol {

// Standard CRC-32C: init 0xFFFFFFFF, reflected, final xor 0xFFFFFFFF.
// crc32c("123456789") == 0xE3069283.
std::uint32_t crc32c(std::span<const std::uint8_t> bytes);

}  // namespace dentmark::protocol
