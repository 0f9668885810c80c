#pragma once
// Encoder and decoder of protocol frames (docs/protocol.md). The decoder treats every
// byte as hostile: it checks lengths against hard limits before allocating, never
// reads outside the given span, and reports typed errors with the byte offset.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "dentmark/common/protocol/messages.h"
#include "dentmark/common/protocol/wire_format.h"

namespace dentmark::protocol {

class HmacKey;

struct EncodeOptions {
  std::uint64_t sequence = 0;
  std::optional<double> send_time;  // s since the Unix epoch; the system clock when unset
  const HmacKey* key = nullptr;     // signs the frame when set
};

// Thrown by encode() for messages that could not be decoded again (over a limit,
// non-finite number, string too long or not printable ASCII, non-unit normal...).
class EncodeError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

std::vector<std::uint8_t> encode(const DefectList& list, const EncodeOptions& options);
std::vector<std::uint8_t> encode(const Ack& ack, const EncodeOptions& options);
std::vector<std::uint8_t> encode(const MarkReport& report, const EncodeOptions& options);
std::vector<std::uint8_t> encode(const Status& status, const EncodeOptions& options);
std::vector<std::uint8_t> encode(const ErrorMessage& error, const EncodeOptions& options);
std::vector<std::uint8_t> encode(const Message& message, const EncodeOptions& options);

enum class DecodeErrorKind {
  kTruncated,           // fewer bytes than the header or its lengths announce
  kBadMagic,            // not "DMKL"
  kUnsupportedVersion,  // unknown major version
  kBadEnum,             // message type, flag bit, class, outcome, reason, state or code not defined
  kOverLimit,           // frame size or record count above the hard limits
  kBadLength,           // inner lengths inconsistent, trailing bytes, record size too small
  kBadCrc,              // CRC-32C mismatch
  kUnsigned,            // no HMAC although a key is configured
  kBadHmac,             // HMAC mismatch
  kBadValue,            // non-finite number, non-unit normal, value out of range, bad string
};

const char* to_string(DecodeErrorKind kind);

struct DecodeError {
  DecodeErrorKind kind = DecodeErrorKind::kTruncated;
  std::size_t offset = 0;  // byte offset in the frame where the problem is
  std::string detail;      // one line, e.g. "payload length 2000000 > limit 1048488"

  // "byte <offset>: <kind>: <detail>"
  std::string message() const;
};

struct FrameHeader {
  std::uint8_t major = wire::kMajor;
  std::uint8_t minor = wire::kMinor;
  MessageType type = MessageType::kDefectList;
  std::uint16_t flags = 0;
  std::uint16_t record_size = 0;
  std::uint32_t payload_length = 0;
  std::uint64_t sequence = 0;
  double send_time = 0.0;

  bool is_signed() const { return (flags & wire::kFlagHmac) != 0; }
  // Header + payload + optional HMAC + CRC.
  std::size_t frame_size() const;
};

struct Decoded {
  FrameHeader header;
  Message message;
  bool authenticated = false;  // HMAC verified with the configured key
};

struct DecodeOptions {
  const HmacKey* key = nullptr;                      // when set, unsigned frames and bad HMACs are refused
  std::size_t max_frame_size = wire::kMaxFrameSize;  // may only lower the built-in limit
  std::uint32_t max_records = wire::kMaxRecords;     // may only lower the built-in limit
};

template <typename T>
class Result {
 public:
  Result(T value) : v_(std::move(value)) {}            // NOLINT: implicit on purpose
  Result(DecodeError error) : v_(std::move(error)) {}  // NOLINT
  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }
  const T& value() const { return std::get<0>(v_); }
  T& value() { return std::get<0>(v_); }
  const DecodeError& error() const { return std::get<1>(v_); }

 private:
  std::variant<T, DecodeError> v_;
};

using DecodeResult = Result<Decoded>;

// Reads and checks the fixed header (magic, version, type, flags, limits) from the
// first wire::kHeaderSize bytes. Stream readers call this before allocating the rest
// of a frame: header.frame_size() is then within the limit.
Result<FrameHeader> decode_header(std::span<const std::uint8_t> bytes, const DecodeOptions& options);

// Decodes exactly one frame: 'bytes' must hold the whole frame and nothing else.
DecodeResult decode(std::span<const std::uint8_t> bytes, const DecodeOptions& options);

// SHA-256 of the payload of a frame that decoded (the digest an Ack carries).
Digest payload_digest(std::span<const std::uint8_t> frame);

const char* to_string(MessageType type);
const char* to_string(DefectClass c);
const char* to_string(MarkOutcome o);
const char* to_string(MarkReason r);
const char* to_string(EdgeState s);
const char* to_string(ErrorCode c);

}  // namespace dentmark::protocol
