#pragma once
// Edge side of the host<->edge link: a TCP listener serving several clients, one
// thread each (at most max_clients; more are refused with a 'busy' Error). Every read
// has an idle and a whole-frame deadline, so slow or silent clients cannot hold a
// slot; headers are checked against the limits before a frame is allocated. Frames
// that fail to decode, are unsigned or replayed while a key is configured are
// answered with an Error frame and the connection is closed.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>

#include "dentmark/common/protocol/codec.h"
#include "dentmark/common/protocol/replay_guard.h"
#include "dentmark/common/protocol/socket_io.h"

namespace dentmark::link {

class LinkServerError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ServerOptions {
  std::string bind_address = "0.0.0.0";
  std::uint16_t port = 7878;  // 0: the kernel picks a free port (see LinkServer::port())
  int max_clients = 8;
  protocol::ReadTimeouts timeouts;
  std::chrono::milliseconds write_timeout{2000};
  const protocol::HmacKey* key = nullptr;  // when set: signed frames only, replay window enforced
  double replay_window = 30.0;             // s
  std::size_t max_frame_size = protocol::wire::kMaxFrameSize;
  std::function<double()> clock;  // s since the Unix epoch; the system clock when empty
};

// Sends one message on a connection; false when the peer is gone or the server stops.
using Push = std::function<bool(const protocol::Message&)>;

// A handler's answer: the reply, and optionally a stream that keeps the connection to
// push more messages (a report subscription, docs/protocol.md §8). 'follow' runs on
// the connection's thread after the reply; the connection closes when it returns. It
// must return soon after a push fails.
struct Reply {
  // A plain reply (any message type converts).
  template <typename M>
  requires std::is_constructible_v<protocol::Message, M> Reply(M m)
      : message(std::move(m)) {}  // NOLINT(google-explicit-constructor)
  Reply(protocol::Message m, std::function<void(const Push&)> f)
      : message(std::move(m)), follow(std::move(f)) {}
  protocol::Message message;
  std::function<void(const Push&)> follow;
};

// Handles one accepted frame (decoded, authenticated and not replayed) and returns
// the reply. Called from connection threads: must be thread-safe.
using Handler = std::function<Reply(const protocol::Decoded& decoded, std::span<const std::uint8_t> frame)>;

struct ServerStats {
  std::atomic<std::uint64_t> connections{0};
  std::atomic<std::uint64_t> refused_busy{0};
  std::atomic<std::uint64_t> frames_ok{0};
  std::atomic<std::uint64_t> frames_refused{0};
};

class LinkServer {
 public:
  LinkServer(ServerOptions options, Handler handler);
  ~LinkServer();
  LinkServer(const LinkServer&) = delete;
  LinkServer& operator=(const LinkServer&) = delete;

  // Binds and listens, then serves from a background thread. Throws LinkServerError.
  void start();
  // Refuses new connections and sends nothing more; the connections' threads end as
  // soon as what they wait for returns (a job they follow: Station::stop wakes them).
  void begin_stop();
  // begin_stop(), then waits for every connection's thread and closes the sockets.
  // Idempotent.
  void stop();
  std::uint16_t port() const { return port_; }
  const ServerStats& stats() const { return stats_; }

 private:
  struct Connection {
    int fd = -1;
    std::string peer;
    std::thread thread;
    std::atomic<bool> done{false};
  };

  void accept_loop();
  void serve(Connection& c);
  void reap(bool all);
  bool reply(Connection& c, const protocol::Message& m);
  void refuse(Connection& c, protocol::ErrorCode code, std::uint64_t sequence, std::size_t offset,
              const std::string& text);
  double now() const;

  ServerOptions options_;
  Handler handler_;
  protocol::ReplayGuard replay_;
  int listen_fd_ = -1;
  int stop_fd_ = -1;
  std::uint16_t port_ = 0;
  std::thread acceptor_;
  std::mutex mutex_;
  std::list<std::unique_ptr<Connection>> connections_;
  std::atomic<std::uint64_t> sequence_;
  ServerStats stats_;
  bool running_ = false;
  std::atomic<bool> stopping_{false};
};

}  // namespace dentmark::link
