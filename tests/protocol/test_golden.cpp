// Golden byte vectors (docs/protocol.md, tests/data/protocol/): the encoder must
#include <filesystem>
// produce exactly the stored bytes, and decoding them must give the expected values.
// DENTMARK_WRITE_GOLDEN=1 rewrites the files (only when the format changes on purpose).
#include <gtest/gtest.h>

#include <cstdlib>

#include "dentmark/common/protocol/dml_file.h"
#include "dentmark/common/protocol/hmac_key.h"
#include "golden_messages.h"

namespace dentmark::protocol {
namespace {

const std::string kDir = std::string(DENTMARK_TEST_DATA_DIR) + "/protocol/";

TEST(Golden, EncodingEqualsTheStoredBytesAndDecodingTheValues) {
  const HmacKey key = HmacKey::load(kDir + "golden.key");
  const bool write = std::getenv("DENTMARK_WRITE_GOLDEN") != nullptr;
  for (const auto& v : golden::vectors()) {
    SCOPED_TRACE(v.file);
    EncodeOptions eo;
    eo.sequence = v.sequence;
    eo.send_time = v.send_time;
    eo.key = v.sign ? &key : nullptr;
    const auto bytes = encode(v.message, eo);
    if (write) write_frame_file(kDir + v.file, bytes);
    const auto stored = read_frame_file(kDir + v.file);
    EXPECT_EQ(bytes, stored);
    DecodeOptions dopt;
    dopt.key = v.sign ? &key : nullptr;
    auto r = decode(stored, dopt);
    ASSERT_TRUE(r.ok()) << r.error().message();
    EXPECT_EQ(r.value().message, v.message);
    EXPECT_EQ(r.value().header.sequence, v.sequence);
    EXPECT_EQ(r.value().header.send_time, v.send_time);
    EXPECT_EQ(r.value().authenticated, v.sign);
  }
}

TEST(Golden, OlderMinorFramesStillDecode) {
  for (const auto& v : golden::older_vectors()) {
    SCOPED_TRACE(v.file);
    auto r = decode(read_frame_file(kDir + v.file), DecodeOptions{});
    ASSERT_TRUE(r.ok()) << r.error().message();
    EXPECT_EQ(r.value().header.minor, 0);
    EXPECT_EQ(r.value().message, v.message);
  }
}

TEST(Golden, AckDigestIsTheListsPayloadDigest) {
  const auto list = read_frame_file(kDir + "defect_list.dml");
  auto ack = decode(read_frame_file(kDir + "ack.dml"), DecodeOptions{});
  ASSERT_TRUE(ack.ok());
  EXPECT_EQ(std::get<Ack>(ack.value().message).digest, payload_digest(list));
}

// A few bytes spelled out, so that a change of the layout cannot slip through as a
// consistent change of encoder and golden files together.
TEST(Golden, HeaderBytesAreAsSpecified) {
  const auto b = read_frame_file(kDir + "defect_list.dml");
  ASSERT_GE(b.size(), 40u);
  const std::vector<std::uint8_t> header(b.begin(), b.begin() + 32);
  const std::vector<std::uint8_t> expected{
      'D',  'M',  'K',  'L',  1,    1,                  // magic, major, minor
      1,    0,                                          // type DefectList
      0,    0,                                          // flags
      88,   0,                                          // record size
      0,    0,    0,    0,                              // payload length (checked below)
      1,    0,    0,    0,    0,    0,    0,    0,      // sequence 1
      0x00, 0x00, 0x60, 0x60, 0xB8, 0x13, 0xDA, 0x41};  // 1750000001.5 as binary64
  std::vector<std::uint8_t> h = header;
  h[12] = h[13] = h[14] = h[15] = 0;
  EXPECT_EQ(h, expected);
  const std::uint32_t payload = b[12] | b[13] << 8 | b[14] << 16 | static_cast<std::uint32_t>(b[15]) << 24;
  // head: job 8 + time 8 + "door-FL-0001" 1+12 + "sls" 1+3 = 33; 2 records of 88.
  EXPECT_EQ(payload, 2u + 33u + 4u + 2u * 88u);
  EXPECT_EQ(b.size(), 32u + payload + 4u);
  EXPECT_EQ(b[32], 33);  // head_size
  EXPECT_EQ(b[33], 0);
}

TEST(DmlFile, WritesAtomicallyAndReadsBack) {
  const std::string dir = ::testing::TempDir();
  const std::string path = dir + "/list.dml";
  write_dml(path, golden::door_list());
  EXPECT_EQ(read_dml(path), golden::door_list());
  // No temporary file is left behind.
  int leftovers = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    leftovers += e.path().filename().string().rfind("list.dml.tmp", 0) == 0;
  EXPECT_EQ(leftovers, 0);
  // An unwritable destination leaves nothing and names the file.
  try {
    write_dml("/nonexistent-dir/x.dml", golden::door_list());
    FAIL();
  } catch (const DmlFileError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/nonexistent-dir/x.dml: ", 0), 0u) << e.what();
  }
  // A damaged file: one line with file, byte offset and kind.
  auto bytes = read_frame_file(path);
  bytes[40] ^= 0x10;
  write_frame_file(path, bytes);
  try {
    read_dml(path);
    FAIL();
  } catch (const DmlFileError& e) {
    ASSERT_TRUE(e.is_decode_error());
    EXPECT_EQ(e.decode_error()->kind, DecodeErrorKind::kBadCrc);
    EXPECT_EQ(std::string(e.what()),
              path + ": byte " + std::to_string(bytes.size() - 4) + ": bad CRC: CRC-32C mismatch");
  }
  // Another message type is not a defect list.
  EXPECT_THROW(read_dml(kDir + "ack.dml"), DmlFileError);
}

}  // namespace
}  // namespace dentmark::protocol
