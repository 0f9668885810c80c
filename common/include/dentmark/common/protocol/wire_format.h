#pragma once
// Constants of the binary frame format (docs/protocol.md is the normative text).
// Every multi-byte field is little-endian; floats are IEEE-754 binary64.

#include <array>
#include <cstddef>
#include <cstdint>

namespace dentmark::protocol {

enum class MessageType : std::uint16_t {
  kDefectList = 1,
  kAck = 2,
  kMarkReport = 3,
  kStatus = 4,
  kError = 5,
};

namespace wire {

inline constexpr std::array<std::uint8_t, 4> kMagic{'D', 'M', 'K', 'L'};
inline constexpr std::uint8_t kMajor = 1;
inline constexpr std::uint8_t kMinor = 1;  // 1.1: Status appends the job's progress

inline constexpr std::size_t kHeaderSize = 32;
inline constexpr std::size_t kHmacSize = 32;  // HMAC-SHA-256
inline constexpr std::size_t kCrcSize = 4;    // CRC-32C

// Header byte offsets.
inline constexpr std::size_t kOffMagic = 0;
inline constexpr std::size_t kOffMajor = 4;
inline constexpr std::size_t kOffMinor = 5;
inline constexpr std::size_t kOffType = 6;
inline constexpr std::size_t kOffFlags = 8;
inline constexpr std::size_t kOffRecordSize = 10;
inline constexpr std::size_t kOffPayloadLength = 12;
inline constexpr std::size_t kOffSequence = 16;
inline constexpr std::size_t kOffSendTime = 24;

inline constexpr std::uint16_t kFlagHmac = 0x0001;  // a 32-byte HMAC-SHA-256 precedes the CRC
inline constexpr std::uint16_t kKnownFlags = kFlagHmac;

// Hard limits, checked before anything is allocated.
inline constexpr std::size_t kMaxFrameSize = 1u << 20;  // bytes, whole frame
inline constexpr std::uint32_t kMaxRecords = 4096;      // defects per list, marks per report
inline constexpr std::size_t kMaxStringLength = 255;    // u8 length prefix

// Sizes at minor 0. A newer minor only appends: heads and records may be longer.
inline constexpr std::uint16_t kDefectRecordSize = 88;
inline constexpr std::uint16_t kMarkRecordSize = 48;

inline constexpr std::size_t kMaxPayloadLength = kMaxFrameSize - kHeaderSize - kHmacSize - kCrcSize;

}  // namespace wire
}  // namespace dentmark::protocol
