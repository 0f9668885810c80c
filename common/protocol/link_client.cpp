#include "dentmark/common/protocol/link_client.h"

#include <openssl/rand.h>
#include <unistd.h>

#include <thread>

#include "dentmark/common/protocol/socket_io.h"

namespace dentmark::protocol {

std::uint64_t random_sequence_start() {
  std::uint64_t v = 0;
  if (RAND_bytes(reinterpret_cast<unsigned char*>(&v), sizeof v) != 1)
    throw LinkError("RAND_bytes failed (OpenSSL)");
  return (v >> 2) + 1;  // 62 bits, never 0: counting up cannot wrap in practice
}

LinkClient::LinkClient(ClientOptions options)
    : options_(std::move(options)), sequence_(random_sequence_start()) {}

LinkClient::~LinkClient() {
  disconnect();
}

void LinkClient::disconnect() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

bool LinkClient::ensure_connected(std::string* why) {
  if (fd_ >= 0) return true;
  fd_ = connect_tcp(options_.host, options_.port, options_.connect_timeout, why);
  return fd_ >= 0;
}

Decoded LinkClient::request(const Message& message) {
  const std::string endpoint = options_.host + ":" + std::to_string(options_.port);
  std::string why = "no attempt";
  auto delay = options_.retry_delay;
  const int attempts = std::max(1, options_.attempts);
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    if (attempt > 1) {
      std::this_thread::sleep_for(delay);
      delay *= 2;
    }
    if (!ensure_connected(&why)) continue;
    // A fresh sequence and send time per attempt: a resent copy is not a replay.
    EncodeOptions eo;
    eo.sequence = sequence_++;
    eo.key = options_.key;
    if (options_.clock) eo.send_time = options_.clock();
    const auto frame = encode(message, eo);
    last_digest_ = payload_digest(frame);
    if (!write_all(fd_, frame, options_.reply_timeout, &why)) {
      disconnect();
      continue;
    }
    DecodeOptions dopt;
    dopt.key = options_.key;
    ReadTimeouts t{options_.reply_timeout, options_.reply_timeout};
    ReadFrame r = read_frame(fd_, t, dopt);
    if (r.status == IoStatus::kBadFrame) {
      disconnect();
      throw LinkError(endpoint + ": bad reply: " + r.error.message());
    }
    if (r.status != IoStatus::kOk) {
      why = std::string(to_string(r.status)) + (r.detail.empty() ? "" : ": " + r.detail) +
            " waiting for the reply";
      disconnect();
      // A reply that timed out may still be processed by the edge; retrying is safe
      // because the edge keys jobs by job id and acks duplicates again.
      continue;
    }
    auto d = decode(r.frame, dopt);
    if (!d) {
      disconnect();
      throw LinkError(endpoint + ": bad reply: " + d.error().message());
    }
    // The edge closes the connection after every Error it sends.
    if (std::holds_alternative<ErrorMessage>(d.value().message)) disconnect();
    return std::move(d.value());
  }
  throw LinkError(endpoint + ": " + why + " (after " + std::to_string(attempts) + " attempts)");
}

std::optional<Decoded> LinkClient::receive(std::chrono::milliseconds timeout) {
  const std::string endpoint = options_.host + ":" + std::to_string(options_.port);
  if (fd_ < 0) throw LinkError(endpoint + ": not connected");
  DecodeOptions dopt;
  dopt.key = options_.key;
  ReadFrame r = read_frame(fd_, ReadTimeouts{timeout, options_.reply_timeout}, dopt);
  if (r.status == IoStatus::kIdle) {
    disconnect();
    return std::nullopt;
  }
  if (r.status != IoStatus::kOk) {
    disconnect();
    throw LinkError(endpoint + ": " +
                    (r.status == IoStatus::kBadFrame
                         ? "bad frame: " + r.error.message()
                         : std::string(to_string(r.status)) + (r.detail.empty() ? "" : ": " + r.detail)));
  }
  auto d = decode(r.frame, dopt);
  if (!d) {
    disconnect();
    throw LinkError(endpoint + ": bad frame: " + d.error().message());
  }
  if (std::holds_alternative<ErrorMessage>(d.value().message)) disconnect();
  return std::move(d.value());
}

}  // namespace dentmark::protocol
