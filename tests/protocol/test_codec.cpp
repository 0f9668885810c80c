// Codec properties: round trips of random messages, every single-byte corruption
// and every truncation rejected, limits checked before allocation, typed errors with
// offsets, forward compatibility of minor versions, HMAC.
#include <gtest/gtest.h>

#include <random>

#include "dentmark/common/protocol/codec.h"
#include "dentmark/common/protocol/crc32c.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "test_support.h"

namespace dentmark::protocol {
namespace {

using test::random_list;
using test::reseal;

EncodeOptions at(std::uint64_t seq, const HmacKey* key = nullptr) {
  EncodeOptions o;
  o.sequence = seq;
  o.send_time = 1.75e9;
  o.key = key;
  return o;
}

DefectList small_list() {
  DefectList l;
  l.job_id = 7;
  l.panel_id = "door-L";
  l.scan_time = 1.75e9;
  Defect d;
  d.id = 1;
  d.position = {0.1, 0.2, 0.3};
  d.height = -0.0004;
  d.diameter = 0.012;
  d.area = 1.1e-4;
  d.score = 0.9;
  l.defects.push_back(d);
  d.id = 2;
  d.defect_class = DefectClass::kBump;
  d.normal = Eigen::Vector3d(0, 0.6, 0.8);
  l.defects.push_back(d);
  return l;
}

TEST(Crc32c, StandardCheckValue) {
  const std::string s = "123456789";
  EXPECT_EQ(crc32c(std::span(reinterpret_cast<const std::uint8_t*>(s.data()), s.size())), 0xE3069283u);
  EXPECT_EQ(crc32c({}), 0u);
  // RFC 3720 B.4: 32 bytes of zeros.
  std::vector<std::uint8_t> zeros(32, 0);
  EXPECT_EQ(crc32c(zeros), 0x8A9136AAu);
}

TEST(Codec, RandomDefectListsRoundTrip) {
  std::mt19937_64 rng(1234);
  for (int i = 0; i < 300; ++i) {
    const DefectList l = random_list(rng, i < 290 ? 20 : 4096);
    const auto f = encode(l, at(static_cast<std::uint64_t>(i)));
    auto r = decode(f, {});
    ASSERT_TRUE(r.ok()) << r.error().message();
    EXPECT_EQ(std::get<DefectList>(r.value().message), l);  // bit-exact doubles
    EXPECT_EQ(r.value().header.sequence, static_cast<std::uint64_t>(i));
    EXPECT_EQ(r.value().header.send_time, 1.75e9);
    EXPECT_EQ(f.size(), r.value().header.frame_size());
    EXPECT_FALSE(r.value().authenticated);
  }
}

TEST(Codec, RandomOtherMessagesRoundTrip) {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    Ack a{rng(), rng(), static_cast<std::uint32_t>(rng() % 4097), {}};
    for (auto& b : a.digest) b = static_cast<std::uint8_t>(rng());
    MarkReport m;
    m.job_id = rng();
    for (std::size_t k = 0, n = rng() % 30; k < n; ++k) {
      Mark mk;
      mk.defect_id = static_cast<std::uint32_t>(rng());
      mk.outcome = static_cast<MarkOutcome>(rng() % 3);
      mk.reason =
          mk.outcome == MarkOutcome::kMarked ? MarkReason::kNone : static_cast<MarkReason>(1 + rng() % 7);
      mk.time = 1.75e9 + u(rng);
      mk.tool_position = {u(rng), -u(rng), u(rng)};
      mk.estimated_error = 0.002 * u(rng);
      m.marks.push_back(mk);
    }
    Status s{static_cast<EdgeState>(rng() % 6),
             static_cast<std::uint32_t>(rng()),
             rng(),
             test::random_string(rng, 30),
             1,
             0,
             1000 * u(rng)};
    ErrorMessage e{static_cast<ErrorCode>(1 + rng() % 5), rng(), rng(), static_cast<std::uint32_t>(rng()),
                   test::random_string(rng, 255)};
    for (const Message& msg : {Message(a), Message(m), Message(s), Message(e)}) {
      const auto f = encode(msg, at(5));
      auto r = decode(f, {});
      ASSERT_TRUE(r.ok()) << r.error().message();
      EXPECT_EQ(r.value().message, msg);
    }
  }
}

TEST(Codec, EverySingleByteCorruptionIsRejected) {
  const HmacKey signing_key = test::key_of(0x5A);
  for (const HmacKey* key : {static_cast<const HmacKey*>(nullptr), &signing_key}) {
    const auto f = encode(small_list(), at(3, key));
    DecodeOptions o;
    o.key = key;
    ASSERT_TRUE(decode(f, o).ok());
    std::size_t rejected = 0;
    for (std::size_t i = 0; i < f.size(); ++i) {
      for (int x = 1; x < 256; ++x) {
        auto g = f;
        g[i] ^= static_cast<std::uint8_t>(x);
        auto r = decode(g, o);
        EXPECT_FALSE(r.ok()) << "byte " << i << " xor " << x;
        rejected += !r.ok();
      }
    }
    EXPECT_EQ(rejected, f.size() * 255);
  }
}

TEST(Codec, EveryTruncationIsRejectedAsTruncated) {
  const auto f = encode(small_list(), at(3));
  for (std::size_t n = 0; n < f.size(); ++n) {
    auto r = decode(std::span(f).first(n), {});
    ASSERT_FALSE(r.ok()) << n;
    EXPECT_EQ(r.error().kind, DecodeErrorKind::kTruncated) << n << ": " << r.error().message();
    EXPECT_EQ(r.error().offset, n);
  }
  auto longer = f;
  longer.push_back(0);
  auto r = decode(longer, {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kBadLength);
  EXPECT_EQ(r.error().offset, f.size());
}

TEST(Codec, TypedErrorsCarryTheOffset) {
  const auto good = encode(small_list(), at(3));
  auto expect = [&](std::vector<std::uint8_t> f, DecodeErrorKind kind, std::size_t offset, bool seal = true) {
    if (seal) reseal(f);
    auto r = decode(f, {});
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.error().kind, kind) << r.error().message();
    EXPECT_EQ(r.error().offset, offset) << r.error().message();
  };
  auto f = good;
  f[1] = 'X';
  expect(f, DecodeErrorKind::kBadMagic, 1);
  f = good;
  f[4] = 2;
  expect(f, DecodeErrorKind::kUnsupportedVersion, 4);
  f = good;
  test::put_u16(f, 6, 9);
  expect(f, DecodeErrorKind::kBadEnum, 6);
  f = good;
  test::put_u16(f, 8, 0x0100);
  expect(f, DecodeErrorKind::kBadEnum, 8);
  f = good;
  f[good.size() - 1] ^= 1;
  expect(f, DecodeErrorKind::kBadCrc, good.size() - 4, false);
  // First record starts after the header, head_size, the head and record_count.
  const std::size_t head = 2 + 8 + 8 + 1 + 6 + 1 + 3;
  const std::size_t rec = wire::kHeaderSize + head + 4;
  f = good;
  f[rec + 4] = 7;  // defect class
  expect(f, DecodeErrorKind::kBadEnum, rec + 4);
  f = good;
  f[rec + 32 + 7] = 0x7F;  // normal x = NaN
  f[rec + 32 + 6] = 0xF8;
  expect(f, DecodeErrorKind::kBadValue, rec + 32);
  f = good;
  f[rec + 80 + 7] = 0x40;  // score 2.0-ish
  expect(f, DecodeErrorKind::kBadValue, rec + 80);
  f = good;
  f[wire::kHeaderSize + 2 + 16 + 1] = 0x01;  // control character in panel_id
  expect(f, DecodeErrorKind::kBadValue, wire::kHeaderSize + 2 + 16 + 1);
  f = good;
  f[rec + wire::kDefectRecordSize] = 1;  // second defect gets id 1 again
  expect(f, DecodeErrorKind::kBadValue, rec + wire::kDefectRecordSize);
}

TEST(Codec, LimitsAreCheckedBeforeAllocation) {
  auto f = encode(small_list(), at(3));
  // A header announcing 4 GiB: refused from the header alone, at the length field.
  test::put_u32(f, wire::kOffPayloadLength, 0xFFFFFFF0u);
  auto h = decode_header(std::span(f).first(wire::kHeaderSize), {});
  ASSERT_FALSE(h.ok());
  EXPECT_EQ(h.error().kind, DecodeErrorKind::kOverLimit);
  EXPECT_EQ(h.error().offset, wire::kOffPayloadLength);
  // A caller may lower the limit.
  DecodeOptions small;
  small.max_frame_size = 100;
  auto r = decode(encode(small_list(), at(3)), small);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kOverLimit);
  // record_count above the limit inside a frame of legal size: refused at the count.
  DefectList l = small_list();
  l.defects.clear();
  auto g = encode(l, at(3));
  const std::size_t count_at = g.size() - 4 - 4;
  test::put_u32(g, count_at, wire::kMaxRecords + 1);
  reseal(g);
  r = decode(g, {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kOverLimit);
  EXPECT_EQ(r.error().offset, count_at);
  // A count that does not match the payload's size is refused before resize().
  test::put_u32(g, count_at, 1000);
  reseal(g);
  r = decode(g, {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kBadLength);
  // The encoder refuses what the decoder would.
  l.defects.resize(wire::kMaxRecords + 1);
  for (std::uint32_t i = 0; i < l.defects.size(); ++i) l.defects[i].id = i;
  EXPECT_THROW(encode(l, at(1)), EncodeError);
}

TEST(Codec, EncoderRefusesInvalidValues) {
  DefectList l = small_list();
  l.defects[0].normal = {0, 0, 2};
  EXPECT_THROW(encode(l, at(1)), EncodeError);
  l = small_list();
  l.defects[1].id = l.defects[0].id;
  EXPECT_THROW(encode(l, at(1)), EncodeError);
  l = small_list();
  l.panel_id = std::string(256, 'a');
  EXPECT_THROW(encode(l, at(1)), EncodeError);
  l = small_list();
  l.panel_id = "tab\there";
  EXPECT_THROW(encode(l, at(1)), EncodeError);
  l = small_list();
  l.defects[0].height = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(encode(l, at(1)), EncodeError);
  Mark m;
  m.outcome = MarkOutcome::kSkipped;  // reason none: inconsistent
  EXPECT_THROW(encode(MarkReport{1, {m}}, at(1)), EncodeError);
}

// A newer minor appends fields to the head and to each record; this build reads the
// known prefix and skips the rest, using head_size and record_size.
TEST(Codec, NewerMinorIsReadByItsKnownPrefix) {
  const DefectList l = small_list();
  const auto f = encode(l, at(3));
  const std::size_t head_size = f[wire::kHeaderSize] | f[wire::kHeaderSize + 1] << 8;
  const std::size_t head_end = wire::kHeaderSize + 2 + head_size;
  const std::size_t extra_head = 5;
  const std::size_t extra_rec = 8;
  std::vector<std::uint8_t> g(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(head_end));
  g.insert(g.end(), extra_head, 0xEE);
  g.insert(g.end(), f.begin() + static_cast<std::ptrdiff_t>(head_end),
           f.begin() + static_cast<std::ptrdiff_t>(head_end + 4));
  for (std::size_t i = 0; i < l.defects.size(); ++i) {
    const auto rec = f.begin() + static_cast<std::ptrdiff_t>(head_end + 4 + i * wire::kDefectRecordSize);
    g.insert(g.end(), rec, rec + wire::kDefectRecordSize);
    g.insert(g.end(), extra_rec, 0xAB);
  }
  const std::size_t payload = g.size() - wire::kHeaderSize;
  g.insert(g.end(), 4, 0);
  g[wire::kOffMinor] = 3;
  test::put_u16(g, wire::kOffRecordSize, wire::kDefectRecordSize + extra_rec);
  test::put_u32(g, wire::kOffPayloadLength, static_cast<std::uint32_t>(payload));
  test::put_u16(g, wire::kHeaderSize, static_cast<std::uint16_t>(head_size + extra_head));
  reseal(g);
  auto r = decode(g, {});
  ASSERT_TRUE(r.ok()) << r.error().message();
  EXPECT_EQ(std::get<DefectList>(r.value().message), l);
  EXPECT_EQ(r.value().header.minor, 3);
  // The same bytes claiming minor 0 are refused: minor 0 knows the exact sizes.
  g[wire::kOffMinor] = 0;
  reseal(g);
  r = decode(g, {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kBadLength);
  EXPECT_EQ(r.error().offset, wire::kOffRecordSize);
}

TEST(Codec, HmacWrongKeyAndUnsignedAreRefused) {
  const HmacKey key = test::key_of(0x11);
  const HmacKey other = test::key_of(0x12);
  DecodeOptions with_key;
  with_key.key = &key;
  const auto signed_frame = encode(small_list(), at(3, &key));
  auto r = decode(signed_frame, with_key);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.value().authenticated);
  EXPECT_TRUE(r.value().header.is_signed());
  // Without a key the frame still decodes but is not authenticated.
  r = decode(signed_frame, {});
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r.value().authenticated);
  DecodeOptions wrong;
  wrong.key = &other;
  r = decode(signed_frame, wrong);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kBadHmac);
  EXPECT_EQ(r.error().offset, signed_frame.size() - 4 - 32);
  r = decode(encode(small_list(), at(3)), with_key);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kUnsigned);
  // Altering a signed frame and fixing its CRC does not help.
  auto g = signed_frame;
  g[40] ^= 1;
  reseal(g);
  r = decode(g, with_key);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().kind, DecodeErrorKind::kBadHmac);
}

TEST(Codec, PayloadDigestIgnoresHeaderAndSignature) {
  const HmacKey key = test::key_of(0x11);
  const auto a = encode(small_list(), at(3));
  const auto b = encode(small_list(), at(99, &key));
  EXPECT_EQ(payload_digest(a), payload_digest(b));
  DefectList l = small_list();
  l.job_id = 8;
  EXPECT_NE(payload_digest(a), payload_digest(encode(l, at(3))));
}

TEST(HmacKeyFile, ParsesHexAndRejectsBadText) {
  const std::string hex(64, 'a');
  EXPECT_NO_THROW(HmacKey::parse("# comment\n" + hex.substr(0, 32) + "\n  " + hex.substr(32) + "\n", "k"));
  try {
    HmacKey::parse("# c\nabcz\n", "site.key");
    FAIL();
  } catch (const KeyFileError& e) {
    EXPECT_STREQ(e.what(), "site.key:2: column 4: not a hexadecimal digit");
  }
  EXPECT_THROW(HmacKey::parse(std::string(62, 'a'), "k"), KeyFileError);   // 31 bytes
  EXPECT_THROW(HmacKey::parse(std::string(65, 'a'), "k"), KeyFileError);   // odd
  EXPECT_THROW(HmacKey::parse(std::string(258, 'a'), "k"), KeyFileError);  // 129 bytes
  EXPECT_THROW(HmacKey::load("/nonexistent/key"), KeyFileError);
  // HMAC is deterministic and depends on the key.
  const HmacKey k1 = test::key_of(1);
  const std::vector<std::uint8_t> msg{1, 2, 3};
  EXPECT_EQ(k1.mac(msg), k1.mac(msg));
  EXPECT_NE(k1.mac(msg), test::key_of(2).mac(msg));
}

}  // namespace
}  // namespace dentmark::protocol
