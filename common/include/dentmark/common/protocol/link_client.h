#pragma once
// Host side of the link: sends one message and waits for the edge's reply, with
// timeouts, reconnecting and retrying (with a fresh sequence number) when the
// connection fails.

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "dentmark/common/protocol/codec.h"

namespace dentmark::protocol {

class LinkError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ClientOptions {
  std::string host = "127.0.0.1";
  std::uint16_t port = 7878;
  std::chrono::milliseconds connect_timeout{2000};
  std::chrono::milliseconds reply_timeout{5000};
  int attempts = 3;                            // connections tried before giving up
  std::chrono::milliseconds retry_delay{200};  // doubled after each failed attempt
  const HmacKey* key = nullptr;                // signs requests and requires signed replies
  std::function<double()> clock;               // send_time source, s since the epoch (default: system clock)
};

class LinkClient {
 public:
  explicit LinkClient(ClientOptions options);
  ~LinkClient();
  LinkClient(const LinkClient&) = delete;
  LinkClient& operator=(const LinkClient&) = delete;

  // Sends 'message' and returns the reply (an Ack, Error, ...). Reconnects and resends
  // on connection failures; throws LinkError after the last attempt, naming the
  // endpoint and the reason. A reply that fails to decode also throws.
  Decoded request(const Message& message);

  // After a request that opened a subscription (docs/protocol.md §8): the next frame
  // the edge pushes on this connection, or nullopt when none came within 'timeout'
  // (the connection is then dropped). Throws LinkError when the connection fails or the
  // frame does not decode.
  std::optional<Decoded> receive(std::chrono::milliseconds timeout);

  // Payload digest of the last frame sent (what an Ack should echo).
  const Digest& last_digest() const { return last_digest_; }
  std::uint64_t last_sequence() const { return sequence_ - 1; }

 private:
  bool ensure_connected(std::string* why);
  void disconnect();

  ClientOptions options_;
  int fd_ = -1;
  std::uint64_t sequence_;
  Digest last_digest_{};
};

// Random 62-bit start for a sender's sequence numbers (OpenSSL RAND_bytes).
std::uint64_t random_sequence_start();

}  // namespace dentmark::protocol
