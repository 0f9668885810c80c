// Host-to-edge link over loopback: acks, several concurrent clients, slow and silent
// clients, partial frames, oversize headers refused before the payload arrives,
// authentication and replay, reconnection.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <thread>

#include "dentmark/common/protocol/hmac_key.h"
#include "dentmark/common/protocol/link_client.h"
#include "dentmark/common/protocol/socket_io.h"
#include "dentmark/firmware/link/link_server.h"
#include "job_inbox.h"
#include "test_support.h"

namespace dentmark::link {
namespace {

namespace pr = protocol;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

double wall() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

struct Edge {
  explicit Edge(ServerOptions o = {}) {
    o.bind_address = "127.0.0.1";
    if (o.port == 7878) o.port = 0;
    server = std::make_unique<LinkServer>(o, [this](const pr::Decoded& d, std::span<const std::uint8_t> f) {
      return inbox.handle(d, f, wall());
    });
    server->start();
  }
  JobInbox inbox;
  std::unique_ptr<LinkServer> server;
};

pr::ClientOptions client_for(const Edge& e, const pr::HmacKey* key = nullptr) {
  pr::ClientOptions c;
  c.port = e.server->port();
  c.key = key;
  c.reply_timeout = 3000ms;
  return c;
}

pr::DefectList list_of(std::uint64_t job, std::size_t n) {
  std::mt19937_64 rng(job);
  auto l = pr::test::random_list(rng, 0);
  l.job_id = job;
  auto more = pr::test::random_list(rng, 50);
  more.defects.resize(std::min(n, more.defects.size()));
  while (more.defects.size() < n) {
    pr::Defect d;
    d.id = static_cast<std::uint32_t>(1000 + more.defects.size());
    more.defects.push_back(d);
  }
  l.defects = more.defects;
  return l;
}

int raw_connect(const Edge& e) {
  std::string why;
  const int fd = pr::connect_tcp("127.0.0.1", e.server->port(), 2000ms, &why);
  EXPECT_GE(fd, 0) << why;
  return fd;
}

pr::ReadFrame raw_reply(int fd, std::chrono::milliseconds timeout = 3000ms) {
  return pr::read_frame(fd, {timeout, timeout}, {});
}

pr::ErrorMessage expect_error(int fd) {
  auto r = raw_reply(fd);
  EXPECT_EQ(r.status, pr::IoStatus::kOk) << pr::to_string(r.status);
  if (r.status != pr::IoStatus::kOk) return {};
  auto d = pr::decode(r.frame, {});
  EXPECT_TRUE(d.ok());
  if (!d.ok()) return {};
  const auto* e = std::get_if<pr::ErrorMessage>(&d.value().message);
  EXPECT_NE(e, nullptr);
  return e ? *e : pr::ErrorMessage{};
}

// After an Error the server closes: the next read sees end of stream.
void expect_closed(int fd) {
  EXPECT_EQ(raw_reply(fd, 2000ms).status, pr::IoStatus::kClosed);
}

TEST(Link, AcksADefectListWithItsDigest) {
  Edge edge;
  pr::LinkClient client(client_for(edge));
  const auto list = list_of(42, 17);
  const auto reply = client.request(list);
  const auto* ack = std::get_if<pr::Ack>(&reply.message);
  ASSERT_NE(ack, nullptr);
  EXPECT_EQ(ack->job_id, 42u);
  EXPECT_EQ(ack->count, 17u);
  EXPECT_EQ(ack->acked_sequence, client.last_sequence());
  EXPECT_EQ(ack->digest, client.last_digest());
  EXPECT_EQ(ack->digest, pr::payload_digest(pr::encode(list, {})));
  const auto job = edge.inbox.last_job();
  ASSERT_TRUE(job.has_value());
  EXPECT_EQ(job->list, list);
  // A second list on the same connection replaces the job.
  const auto second = client.request(list_of(43, 2));
  EXPECT_EQ(std::get<pr::Ack>(second.message).job_id, 43u);
  EXPECT_EQ(edge.inbox.last_job()->list.job_id, 43u);
  EXPECT_EQ(edge.inbox.jobs_received(), 2u);
  // Anything but a DefectList is answered 'unsupported'.
  const auto err = client.request(pr::Status{});
  EXPECT_EQ(std::get<pr::ErrorMessage>(err.message).code, pr::ErrorCode::kUnsupported);
}

TEST(Link, ServesConcurrentClients) {
  ServerOptions o;
  o.max_clients = 8;
  Edge edge(o);
  std::atomic<int> acked{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t)
    threads.emplace_back([&, t] {
      pr::LinkClient c(client_for(edge));
      for (int i = 0; i < 10; ++i) {
        const auto l = list_of(static_cast<std::uint64_t>(t * 100 + i), static_cast<std::size_t>(i * 7));
        const auto r = c.request(l);
        const auto* a = std::get_if<pr::Ack>(&r.message);
        if (a && a->job_id == l.job_id && a->count == l.defects.size() && a->digest == c.last_digest())
          ++acked;
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(acked.load(), 80);
  EXPECT_EQ(edge.server->stats().frames_ok.load(), 80u);
  EXPECT_EQ(edge.inbox.jobs_received(), 80u);
}

TEST(Link, PartialFramesAreReassembled) {
  Edge edge;
  const auto frame = pr::encode(list_of(5, 30), {});
  const int fd = raw_connect(edge);
  // Odd-sized pieces with pauses: the header itself arrives in three parts.
  std::size_t at = 0;
  for (std::size_t piece : {3u, 11u, 29u, 500u, 7u}) {
    piece = std::min(piece, frame.size() - at);
    std::string why;
    ASSERT_TRUE(pr::write_all(fd, std::span(frame).subspan(at, piece), 1000ms, &why)) << why;
    at += piece;
    std::this_thread::sleep_for(20ms);
  }
  ASSERT_TRUE(pr::write_all(fd, std::span(frame).subspan(at), 1000ms, nullptr));
  auto r = raw_reply(fd);
  ASSERT_EQ(r.status, pr::IoStatus::kOk);
  auto d = pr::decode(r.frame, {});
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(std::get<pr::Ack>(d.value().message).count, 30u);
  ::close(fd);
}

TEST(Link, SlowAndSilentClientsAreCutOffWithoutBlockingOthers) {
  ServerOptions o;
  o.timeouts.idle = 1000ms;
  o.timeouts.frame = 800ms;
  Edge edge(o);
  const auto frame = pr::encode(list_of(6, 3), {});
  const int silent = raw_connect(edge);
  const int slow = raw_connect(edge);
  // The slowloris sends one byte every 100 ms: 20 bytes miss the 800 ms frame deadline.
  std::thread trickle([&] {
    for (std::size_t i = 0; i < 20; ++i) {
      if (!pr::write_all(slow, std::span(frame).subspan(i, 1), 200ms, nullptr)) break;
      std::this_thread::sleep_for(100ms);
    }
  });
  // Meanwhile a normal client is served at once.
  const auto t0 = Clock::now();
  pr::LinkClient c(client_for(edge));
  EXPECT_TRUE(std::holds_alternative<pr::Ack>(c.request(list_of(7, 1)).message));
  EXPECT_LT(Clock::now() - t0, 700ms);  // not queued behind the stalled connections (≥ 800 ms)
  // Both stalled connections are closed by the server within their deadlines.
  const auto t1 = Clock::now();
  EXPECT_EQ(raw_reply(silent, 3000ms).status, pr::IoStatus::kClosed);
  EXPECT_LT(Clock::now() - t1, 2000ms);
  trickle.join();
  auto r = raw_reply(slow, 3000ms);
  EXPECT_TRUE(r.status == pr::IoStatus::kClosed || r.status == pr::IoStatus::kError)
      << pr::to_string(r.status);
  EXPECT_FALSE(edge.inbox.last_job()->list.job_id == 6u);
  ::close(silent);
  ::close(slow);
}

TEST(Link, OversizeFrameIsRefusedFromItsHeader) {
  Edge edge;
  auto frame = pr::encode(list_of(8, 1), {});
  pr::test::put_u32(frame, pr::wire::kOffPayloadLength, 200u << 20);  // 200 MiB announced
  const int fd = raw_connect(edge);
  // Only the header is sent: the refusal cannot have waited for (or allocated) the payload.
  ASSERT_TRUE(pr::write_all(fd, std::span(frame).first(pr::wire::kHeaderSize), 1000ms, nullptr));
  const auto t0 = Clock::now();
  const auto e = expect_error(fd);
  EXPECT_LT(Clock::now() - t0, 1000ms);
  EXPECT_EQ(e.code, pr::ErrorCode::kMalformedFrame);
  EXPECT_EQ(e.byte_offset, pr::wire::kOffPayloadLength);
  EXPECT_NE(e.text.find("over limit"), std::string::npos) << e.text;
  expect_closed(fd);
  ::close(fd);
  EXPECT_FALSE(edge.inbox.last_job().has_value());
}

TEST(Link, GarbageIsRefusedAtTheFirstBadByte) {
  Edge edge;
  const int fd = raw_connect(edge);
  const std::vector<std::uint8_t> junk{'D', 'M', 'X'};
  ASSERT_TRUE(pr::write_all(fd, junk, 1000ms, nullptr));
  const auto e = expect_error(fd);
  EXPECT_EQ(e.code, pr::ErrorCode::kMalformedFrame);
  EXPECT_EQ(e.byte_offset, 2u);
  ::close(fd);
}

TEST(Link, WrongKeyUnsignedAndReplayAreRefused) {
  const pr::HmacKey key = pr::test::key_of(0x33);
  const pr::HmacKey wrong = pr::test::key_of(0x34);
  std::atomic<double> now{wall()};
  ServerOptions o;
  o.key = &key;
  o.replay_window = 30.0;
  o.clock = [&now] { return now.load(); };
  Edge edge(o);
  // The right key: acked, and the reply itself is signed.
  pr::LinkClient good(client_for(edge, &key));
  const auto r = good.request(list_of(9, 2));
  EXPECT_TRUE(std::holds_alternative<pr::Ack>(r.message));
  EXPECT_TRUE(r.authenticated);
  // Wrong key and unsigned: Error 'unauthenticated'.
  for (const pr::HmacKey* k : {&wrong, static_cast<const pr::HmacKey*>(nullptr)}) {
    const int fd = raw_connect(edge);
    pr::EncodeOptions eo;
    eo.key = k;
    eo.sequence = 77;
    ASSERT_TRUE(pr::write_all(fd, pr::encode(list_of(10, 1), eo), 1000ms, nullptr));
    EXPECT_EQ(expect_error(fd).code, pr::ErrorCode::kUnauthenticated);
    expect_closed(fd);
    ::close(fd);
  }
  // Replay: the same signed frame twice (on two connections) is accepted once.
  pr::EncodeOptions eo;
  eo.key = &key;
  eo.sequence = 1234567;
  const auto frame = pr::encode(list_of(11, 1), eo);
  int fd = raw_connect(edge);
  ASSERT_TRUE(pr::write_all(fd, frame, 1000ms, nullptr));
  auto first = raw_reply(fd);
  ASSERT_EQ(first.status, pr::IoStatus::kOk);
  EXPECT_TRUE(std::holds_alternative<pr::Ack>(pr::decode(first.frame, {}).value().message));
  ::close(fd);
  fd = raw_connect(edge);
  ASSERT_TRUE(pr::write_all(fd, frame, 1000ms, nullptr));
  auto e = expect_error(fd);
  EXPECT_EQ(e.code, pr::ErrorCode::kUnauthenticated);
  EXPECT_EQ(e.offending_sequence, 1234567u);
  EXPECT_NE(e.text.find("replay"), std::string::npos) << e.text;
  ::close(fd);
  // A fresh sequence but a send time outside the window: refused as stale.
  eo.sequence = 999;
  eo.send_time = now.load() - 31.0;
  fd = raw_connect(edge);
  ASSERT_TRUE(pr::write_all(fd, pr::encode(list_of(12, 1), eo), 1000ms, nullptr));
  e = expect_error(fd);
  EXPECT_EQ(e.code, pr::ErrorCode::kUnauthenticated);
  EXPECT_NE(e.text.find("window"), std::string::npos) << e.text;
  ::close(fd);
  EXPECT_EQ(edge.inbox.jobs_received(), 2u);  // jobs 9 and 11 only
  // The client refuses unsigned replies when it holds a key.
  Edge open_edge;
  pr::LinkClient signer(client_for(open_edge, &key));
  EXPECT_THROW(signer.request(list_of(13, 1)), pr::LinkError);
}

TEST(Link, TooManyClientsAreToldBusy) {
  ServerOptions o;
  o.max_clients = 2;
  Edge edge(o);
  const int a = raw_connect(edge);
  const int b = raw_connect(edge);
  std::this_thread::sleep_for(100ms);  // both accepted
  const int c = raw_connect(edge);
  EXPECT_EQ(expect_error(c).code, pr::ErrorCode::kBusy);
  ::close(a);
  ::close(b);
  ::close(c);
  // Once they left, the slots are free again (as soon as their threads have ended).
  pr::LinkClient client(client_for(edge));
  bool acked = false;
  for (int i = 0; i < 100 && !acked; ++i) {
    const auto r = client.request(list_of(14, 1));
    acked = std::holds_alternative<pr::Ack>(r.message);
    if (!acked) {
      ASSERT_EQ(std::get<pr::ErrorMessage>(r.message).code, pr::ErrorCode::kBusy);
      std::this_thread::sleep_for(50ms);
    }
  }
  EXPECT_TRUE(acked);
}

TEST(Link, ClientReconnectsAfterTheEdgeRestarts) {
  auto edge = std::make_unique<Edge>();
  const std::uint16_t port = edge->server->port();
  auto opts = client_for(*edge);
  opts.attempts = 5;
  opts.retry_delay = 100ms;
  pr::LinkClient client(opts);
  EXPECT_TRUE(std::holds_alternative<pr::Ack>(client.request(list_of(15, 1)).message));
  edge.reset();  // connection dropped by the edge
  ServerOptions o;
  o.port = port;
  auto again = std::make_unique<Edge>(o);
  EXPECT_TRUE(std::holds_alternative<pr::Ack>(client.request(list_of(16, 1)).message));
  EXPECT_EQ(again->inbox.last_job()->list.job_id, 16u);
  // Nobody listening: a bounded number of attempts, then a clear error.
  again.reset();
  opts.port = port;
  opts.attempts = 2;
  opts.connect_timeout = 200ms;
  pr::LinkClient lonely(opts);
  const auto t0 = Clock::now();
  try {
    lonely.request(list_of(17, 1));
    FAIL();
  } catch (const pr::LinkError& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(port)), std::string::npos) << e.what();
  }
  EXPECT_LT(Clock::now() - t0, 2000ms);
}

}  // namespace
}  // namespace dentmark::link
