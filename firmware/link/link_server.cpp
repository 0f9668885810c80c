#include "dentmark/firmware/link/link_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <optional>

#include "dentmark/common/log.h"
#include "dentmark/common/protocol/link_client.h"

namespace dentmark::link {

LinkServer::LinkServer(ServerOptions options, Handler handler)
    : options_(std::move(options)),
      handler_(std::move(handler)),
      replay_(options_.replay_window),
      sequence_(protocol::random_sequence_start()) {}

LinkServer::~LinkServer() {
  stop();
}

double LinkServer::now() const {
  if (options_.clock) return options_.clock();
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

void LinkServer::start() {
  if (running_) return;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(options_.port);
  if (::inet_pton(AF_INET, options_.bind_address.c_str(), &addr.sin_addr) != 1)
    throw LinkServerError("link: bind address '" + options_.bind_address + "' is not an IPv4 address");
  listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (listen_fd_ < 0) throw LinkServerError(std::string("link: socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::listen(listen_fd_, 16) != 0) {
    const std::string why = std::strerror(errno);
    ::close(listen_fd_);
    listen_fd_ = -1;
    throw LinkServerError("link: cannot listen on " + options_.bind_address + ":" +
                          std::to_string(options_.port) + ": " + why);
  }
  socklen_t len = sizeof addr;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
  stop_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (stop_fd_ < 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
    throw LinkServerError(std::string("link: eventfd: ") + std::strerror(errno));
  }
  running_ = true;
  stopping_ = false;
  acceptor_ = std::thread([this] { accept_loop(); });
}

void LinkServer::begin_stop() {
  if (!running_ || stopping_.exchange(true)) return;
  const std::uint64_t one = 1;
  // Level-triggered and never read: every poll() on stop_fd_ wakes from now on.
  [[maybe_unused]] const auto n = ::write(stop_fd_, &one, sizeof one);
  if (acceptor_.joinable()) acceptor_.join();
}

void LinkServer::stop() {
  if (!running_) return;
  begin_stop();
  running_ = false;
  reap(true);
  ::close(listen_fd_);
  ::close(stop_fd_);
  listen_fd_ = stop_fd_ = -1;
}

void LinkServer::reap(bool all) {
  std::lock_guard lock(mutex_);
  for (auto it = connections_.begin(); it != connections_.end();) {
    Connection& c = **it;
    if (all || c.done.load()) {
      if (c.thread.joinable()) c.thread.join();
      it = connections_.erase(it);
    } else {
      ++it;
    }
  }
}

void LinkServer::accept_loop() {
  for (;;) {
    pollfd p[2] = {{listen_fd_, POLLIN, 0}, {stop_fd_, POLLIN, 0}};
    const int n = ::poll(p, 2, 1000);
    if (n < 0 && errno != EINTR) {
      log::error(std::string("link: poll: ") + std::strerror(errno));
      return;
    }
    if (p[1].revents & POLLIN) return;
    reap(false);
    if (n <= 0 || !(p[0].revents & POLLIN)) continue;
    sockaddr_storage peer{};
    socklen_t plen = sizeof peer;
    const int fd =
        ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&peer), &plen, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) continue;  // EAGAIN, ECONNABORTED, EMFILE: keep serving the others
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    auto c = std::make_unique<Connection>();
    c->fd = fd;
    char host[INET6_ADDRSTRLEN] = "?";
    if (peer.ss_family == AF_INET) {
      const auto* a = reinterpret_cast<sockaddr_in*>(&peer);
      ::inet_ntop(AF_INET, &a->sin_addr, host, sizeof host);
      c->peer = std::string(host) + ":" + std::to_string(ntohs(a->sin_port));
    } else {
      c->peer = "?";
    }
    ++stats_.connections;
    std::lock_guard lock(mutex_);
    if (static_cast<int>(connections_.size()) >= options_.max_clients) {
      ++stats_.refused_busy;
      log::warn("link: " + c->peer + " refused: " + std::to_string(options_.max_clients) +
                " clients connected");
      refuse(*c, protocol::ErrorCode::kBusy, 0, 0, "too many clients");
      ::close(fd);
      continue;
    }
    Connection& ref = *c;
    connections_.push_back(std::move(c));
    ref.thread = std::thread([this, &ref] {
      serve(ref);
      ::close(ref.fd);
      ref.done = true;
    });
  }
}

bool LinkServer::reply(Connection& c, const protocol::Message& m) {
  protocol::EncodeOptions eo;
  eo.sequence = sequence_++;
  eo.send_time = now();
  eo.key = options_.key;
  std::string why;
  const auto frame = protocol::encode(m, eo);
  if (!protocol::write_all(c.fd, frame, options_.write_timeout, &why)) {
    log::warn("link: " + c.peer + ": reply not sent: " + why);
    return false;
  }
  return true;
}

void LinkServer::refuse(Connection& c, protocol::ErrorCode code, std::uint64_t sequence, std::size_t offset,
                        const std::string& text) {
  protocol::ErrorMessage e;
  e.code = code;
  e.offending_sequence = sequence;
  e.byte_offset = static_cast<std::uint32_t>(offset);
  e.text = text.substr(0, protocol::wire::kMaxStringLength);
  for (char& ch : e.text)
    if (ch < 0x20 || ch > 0x7E) ch = '?';  // printable ASCII only
  reply(c, e);
}

void LinkServer::serve(Connection& c) {
  protocol::DecodeOptions dopt;
  dopt.key = options_.key;
  dopt.max_frame_size = options_.max_frame_size;
  log::debug("link: " + c.peer + " connected");
  for (;;) {
    protocol::ReadFrame r = protocol::read_frame(c.fd, options_.timeouts, dopt, stop_fd_);
    if (r.status == protocol::IoStatus::kStopped || r.status == protocol::IoStatus::kClosed) break;
    if (r.status == protocol::IoStatus::kBadFrame) {
      ++stats_.frames_refused;
      log::warn("link: " + c.peer + ": refused frame: " + r.error.message());
      refuse(c, protocol::ErrorCode::kMalformedFrame, 0, r.error.offset, r.error.message());
      break;
    }
    if (r.status != protocol::IoStatus::kOk) {
      log::warn("link: " + c.peer + ": " + protocol::to_string(r.status) +
                (r.detail.empty() ? "" : ": " + r.detail) + "; connection closed");
      break;
    }
    auto d = protocol::decode(r.frame, dopt);
    if (!d) {
      ++stats_.frames_refused;
      const auto kind = d.error().kind;
      const bool auth =
          kind == protocol::DecodeErrorKind::kUnsigned || kind == protocol::DecodeErrorKind::kBadHmac;
      log::warn("link: " + c.peer + ": refused frame: " + d.error().message());
      refuse(c, auth ? protocol::ErrorCode::kUnauthenticated : protocol::ErrorCode::kMalformedFrame, 0,
             d.error().offset, d.error().message());
      break;
    }
    const protocol::FrameHeader& h = d.value().header;
    if (options_.key) {
      const auto verdict = replay_.check(h.sequence, h.send_time, now());
      if (verdict != protocol::ReplayGuard::Verdict::kAccepted) {
        ++stats_.frames_refused;
        log::warn("link: " + c.peer + ": refused frame " + std::to_string(h.sequence) + ": " +
                  protocol::to_string(verdict));
        refuse(c, protocol::ErrorCode::kUnauthenticated, h.sequence, 0, protocol::to_string(verdict));
        break;
      }
    }
    ++stats_.frames_ok;
    std::optional<Reply> answer;
    try {
      answer.emplace(handler_(d.value(), r.frame));
    } catch (const std::exception& e) {
      log::error("link: " + c.peer + ": handler failed: " + e.what());
      refuse(c, protocol::ErrorCode::kInternal, h.sequence, 0, e.what());
      break;
    }
    if (!reply(c, answer->message)) break;
    if (answer->follow) {
      log::debug("link: " + c.peer + " subscribed");
      answer->follow([this, &c](const protocol::Message& m) { return !stopping_ && reply(c, m); });
      break;
    }
  }
  log::debug("link: " + c.peer + " disconnected");
}

}  // namespace dentmark::link
