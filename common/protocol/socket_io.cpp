#include "dentmark/common/protocol/socket_io.h"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace dentmark::protocol {
namespace {

using Clock = std::chrono::steady_clock;

int ms_left(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left <= 0 ? 0 : static_cast<int>(std::min<long long>(left, 1 << 30));
}

// Waits until 'fd' has 'events' or the deadline passes; 1 ready, 0 timeout, -1 error,
// -2 stop requested.
int wait_fd(int fd, short events, Clock::time_point deadline, int stop_fd) {
  for (;;) {
    pollfd p[2] = {{fd, events, 0}, {stop_fd, POLLIN, 0}};
    const int n = ::poll(p, stop_fd >= 0 ? 2 : 1, ms_left(deadline));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return -1;
    if (stop_fd >= 0 && (p[1].revents & POLLIN)) return -2;
    if (n == 0) return Clock::now() >= deadline ? 0 : wait_fd(fd, events, deadline, stop_fd);
    return 1;  // readable, writable, or an error/hangup that the next call reports
  }
}

}  // namespace

const char* to_string(IoStatus s) {
  switch (s) {
    case IoStatus::kOk:
      return "ok";
    case IoStatus::kIdle:
      return "idle timeout";
    case IoStatus::kTimeout:
      return "frame timeout";
    case IoStatus::kClosed:
      return "connection closed";
    case IoStatus::kError:
      return "connection error";
    case IoStatus::kBadFrame:
      return "bad frame";
    case IoStatus::kStopped:
      return "stopped";
  }
  return "?";
}

ReadFrame read_frame(int fd, const ReadTimeouts& timeouts, const DecodeOptions& options, int stop_fd) {
  ReadFrame out;
  std::uint8_t header[wire::kHeaderSize];
  std::size_t have = 0;
  auto deadline = Clock::now() + timeouts.idle;
  bool started = false;
  auto read_into = [&](std::uint8_t* dst, std::size_t want, std::size_t& got) -> bool {
    for (;;) {
      const int w = wait_fd(fd, POLLIN, deadline, stop_fd);
      if (w == -2) {
        out.status = IoStatus::kStopped;
        return false;
      }
      if (w == 0) {
        out.status = started ? IoStatus::kTimeout : IoStatus::kIdle;
        return false;
      }
      if (w < 0) {
        out.status = IoStatus::kError;
        out.detail = std::strerror(errno);
        return false;
      }
      const ssize_t n = ::recv(fd, dst + got, want - got, 0);
      if (n < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK)) continue;
      if (n < 0) {
        out.status = IoStatus::kError;
        out.detail = std::strerror(errno);
        return false;
      }
      if (n == 0) {
        out.status = started ? IoStatus::kError : IoStatus::kClosed;
        if (started) out.detail = "peer closed inside a frame";
        return false;
      }
      got += static_cast<std::size_t>(n);
      if (!started) {
        // The whole frame must now arrive within the frame timeout.
        started = true;
        deadline = Clock::now() + timeouts.frame;
      }
      return true;
    }
  };
  while (have < wire::kHeaderSize) {
    if (!read_into(header, wire::kHeaderSize, have)) return out;
    auto h = decode_header(std::span<const std::uint8_t>(header, have), options);
    if (!h && h.error().kind != DecodeErrorKind::kTruncated) {
      out.status = IoStatus::kBadFrame;
      out.error = h.error();
      return out;
    }
  }
  auto h = decode_header(std::span<const std::uint8_t>(header, wire::kHeaderSize), options);
  if (!h) {
    out.status = IoStatus::kBadFrame;
    out.error = h.error();
    return out;
  }
  // frame_size() is within the limit here, so this allocation is bounded.
  out.frame.resize(h.value().frame_size());
  std::memcpy(out.frame.data(), header, wire::kHeaderSize);
  std::size_t got = wire::kHeaderSize;
  while (got < out.frame.size()) {
    if (!read_into(out.frame.data(), out.frame.size(), got)) {
      out.frame.clear();
      return out;
    }
  }
  out.status = IoStatus::kOk;
  return out;
}

bool write_all(int fd, std::span<const std::uint8_t> bytes, std::chrono::milliseconds timeout,
               std::string* why) {
  const auto deadline = Clock::now() + timeout;
  std::size_t done = 0;
  while (done < bytes.size()) {
    const int w = wait_fd(fd, POLLOUT, deadline, -1);
    if (w == 0) {
      if (why) *why = "write timed out";
      return false;
    }
    if (w < 0) {
      if (why) *why = std::strerror(errno);
      return false;
    }
    const ssize_t n = ::send(fd, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK)) continue;
    if (n < 0) {
      if (why) *why = std::strerror(errno);
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

int connect_tcp(const std::string& host, std::uint16_t port, std::chrono::milliseconds timeout,
                std::string* why) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const int g = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &res);
  if (g != 0) {
    if (why) *why = std::string("cannot resolve '") + host + "': " + gai_strerror(g);
    return -1;
  }
  const auto deadline = Clock::now() + timeout;
  std::string last = "no address";
  int fd = -1;
  for (addrinfo* a = res; a != nullptr && fd < 0; a = a->ai_next) {
    int s = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
    if (s < 0) {
      last = std::strerror(errno);
      continue;
    }
    int rc = ::connect(s, a->ai_addr, a->ai_addrlen);
    if (rc != 0 && errno == EINPROGRESS) {
      const int w = wait_fd(s, POLLOUT, deadline, -1);
      int err = 0;
      socklen_t len = sizeof err;
      if (w == 1 && ::getsockopt(s, SOL_SOCKET, SO_ERROR, &err, &len) == 0 && err == 0) {
        rc = 0;
      } else {
        last = w == 0 ? "connect timed out" : std::strerror(err != 0 ? err : errno);
        rc = -1;
      }
    } else if (rc != 0) {
      last = std::strerror(errno);
    }
    if (rc == 0) {
      const int one = 1;
      ::setsockopt(s, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      fd = s;
    } else {
      ::close(s);
    }
  }
  ::freeaddrinfo(res);
  if (fd < 0 && why) *why = last;
  return fd;
}

bool parse_endpoint(const std::string& text, std::string* host, std::uint16_t* port) {
  std::string h;
  std::string p;
  if (!text.empty() && text.front() == '[') {
    const auto close = text.find(']');
    if (close == std::string::npos || close + 1 >= text.size() || text[close + 1] != ':') return false;
    h = text.substr(1, close - 1);
    p = text.substr(close + 2);
  } else {
    const auto colon = text.rfind(':');
    if (colon == std::string::npos || text.find(':') != colon) return false;
    h = text.substr(0, colon);
    p = text.substr(colon + 1);
  }
  if (h.empty() || p.empty() || p.size() > 5) return false;
  unsigned long v = 0;
  for (char c : p) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<unsigned long>(c - '0');
  }
  if (v == 0 || v > 65535) return false;
  *host = h;
  *port = static_cast<std::uint16_t>(v);
  return true;
}

}  // namespace dentmark::protocol
