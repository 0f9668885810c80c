#pragma once
// Frame transport over stream sockets: each frame is length-prefixed by its own
// header (payload_length), so a reader takes the 32-byte header, checks it against
// the limits, and only then allocates and reads the rest. Every wait has a deadline
// for the whole frame, so a client trickling bytes (slowloris) is cut off.

#include <chrono>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "dentmark/common/protocol/codec.h"

namespace dentmark::protocol {

enum class IoStatus {
  kOk,
  kIdle,      // no byte of a new frame arrived within the idle timeout
  kTimeout,   // a frame started but did not complete within the frame timeout
  kClosed,    // peer closed the connection between frames
  kError,     // socket error, or peer closed inside a frame
  kBadFrame,  // the header failed its checks (see 'error'); nothing more was read
  kStopped,   // the stop descriptor became readable
};

const char* to_string(IoStatus s);

struct ReadFrame {
  IoStatus status = IoStatus::kError;
  std::vector<std::uint8_t> frame;  // whole frame when kOk (not yet CRC/HMAC checked)
  DecodeError error;                // when kBadFrame
  std::string detail;               // when kError
};

struct ReadTimeouts {
  std::chrono::milliseconds idle{60000};  // wait for the first byte of a frame
  std::chrono::milliseconds frame{5000};  // first byte to last byte of one frame
};

// Reads one frame from 'fd' (blocking or not; poll() is used for every wait).
// 'stop_fd' (or -1): when readable, the read is abandoned with kStopped.
ReadFrame read_frame(int fd, const ReadTimeouts& timeouts, const DecodeOptions& options, int stop_fd = -1);

// Writes all bytes within 'timeout' (partial writes resumed). Returns false on timeout
// or error, with a reason in 'why'. Never raises SIGPIPE.
bool write_all(int fd, std::span<const std::uint8_t> bytes, std::chrono::milliseconds timeout,
               std::string* why);

// Connects to host:port (numeric or name) within 'timeout'. Returns the descriptor or
// -1 with a reason in 'why'.
int connect_tcp(const std::string& host, std::uint16_t port, std::chrono::milliseconds timeout,
                std::string* why);

// Splits "HOST:PORT" ("[v6]:PORT" too). Returns false when malformed.
bool parse_endpoint(const std::string& text, std::string* host, std::uint16_t* port);

}  // namespace dentmark::protocol
