// Word-order helpers against golden register values, and the pose encoding.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "dentmark/common/robot_link/register_map.h"
#include "dentmark/common/robot_link/word_order.h"

namespace rl = dentmark::robot_link;
using rl::WordOrder;

namespace {

struct Golden32 {
  std::uint32_t bits;
  std::uint16_t high_first[2];
};

}  // namespace

TEST(WordOrder, U32GoldenValues) {
  std::array<std::uint16_t, 2> r{};
  rl::put_u32(r, 0x12345678u, WordOrder::kHighWordFirst);
  EXPECT_EQ(r[0], 0x1234);
  EXPECT_EQ(r[1], 0x5678);
  rl::put_u32(r, 0x12345678u, WordOrder::kLowWordFirst);
  EXPECT_EQ(r[0], 0x5678);
  EXPECT_EQ(r[1], 0x1234);
  const std::array<std::uint16_t, 2> abcd{0xDEAD, 0xBEEF};
  EXPECT_EQ(rl::get_u32(abcd, WordOrder::kHighWordFirst), 0xDEADBEEFu);
  EXPECT_EQ(rl::get_u32(abcd, WordOrder::kLowWordFirst), 0xBEEFDEADu);
}

TEST(WordOrder, I32GoldenValues) {
  std::array<std::uint16_t, 2> r{};
  rl::put_i32(r, -2, WordOrder::kHighWordFirst);
  EXPECT_EQ(r[0], 0xFFFF);
  EXPECT_EQ(r[1], 0xFFFE);
  rl::put_i32(r, -123456789, WordOrder::kHighWordFirst);  // 0xF8A432EB
  EXPECT_EQ(r[0], 0xF8A4);
  EXPECT_EQ(r[1], 0x32EB);
  EXPECT_EQ(rl::get_i32(r, WordOrder::kHighWordFirst), -123456789);
  const std::array<std::uint16_t, 2> min{0x8000, 0x0000};
  EXPECT_EQ(rl::get_i32(min, WordOrder::kHighWordFirst), std::numeric_limits<std::int32_t>::min());
}

TEST(WordOrder, FloatGoldenValues) {
  // IEEE-754 binary32 patterns, as a controller or mbpoll -B shows them.
  const Golden32 cases[] = {
      {0x3FC00000u, {0x3FC0, 0x0000}},  // 1.5
      {0xC2F6E979u, {0xC2F6, 0xE979}},  // -123.456
      {0x3E800000u, {0x3E80, 0x0000}},  // 0.25 (max_speed)
      {0x80000000u, {0x8000, 0x0000}},  // -0
      {0x7F800000u, {0x7F80, 0x0000}},  // +inf
  };
  const float values[] = {1.5f, -123.456f, 0.25f, -0.0f, std::numeric_limits<float>::infinity()};
  for (std::size_t i = 0; i < std::size(cases); ++i) {
    std::array<std::uint16_t, 2> r{};
    rl::put_f32(r, values[i], WordOrder::kHighWordFirst);
    EXPECT_EQ(r[0], cases[i].high_first[0]) << i;
    EXPECT_EQ(r[1], cases[i].high_first[1]) << i;
    rl::put_f32(r, values[i], WordOrder::kLowWordFirst);
    EXPECT_EQ(r[0], cases[i].high_first[1]) << i;
    EXPECT_EQ(r[1], cases[i].high_first[0]) << i;
    const std::array<std::uint16_t, 2> golden{cases[i].high_first[0], cases[i].high_first[1]};
    const float back = rl::get_f32(golden, WordOrder::kHighWordFirst);
    std::uint32_t bits = 0;
    std::memcpy(&bits, &back, 4);
    EXPECT_EQ(bits, cases[i].bits) << i;
  }
}

TEST(WordOrder, RandomBitPatternsRoundTrip) {
  std::mt19937 rng(7);
  for (int i = 0; i < 20000; ++i) {
    const std::uint32_t bits = rng();
    float f;
    std::memcpy(&f, &bits, 4);
    for (WordOrder order : {WordOrder::kHighWordFirst, WordOrder::kLowWordFirst}) {
      std::array<std::uint16_t, 2> r{};
      rl::put_f32(r, f, order);
      const float g = rl::get_f32(r, order);
      std::uint32_t back = 0;
      std::memcpy(&back, &g, 4);
      ASSERT_EQ(back, bits);  // bit-exact, NaN payloads included
      rl::put_u32(r, bits, order);
      ASSERT_EQ(rl::get_u32(r, order), bits);
    }
  }
}

TEST(WordOrder, ShortSpanThrows) {
  std::array<std::uint16_t, 1> one{};
  EXPECT_THROW(rl::put_u32(one, 1, WordOrder::kHighWordFirst), rl::EncodingError);
  EXPECT_THROW(rl::get_f32(std::span<const std::uint16_t>(one), WordOrder::kHighWordFirst),
               rl::EncodingError);
}

TEST(ScaledRegister, RoundsAndRejectsOutOfRange) {
  EXPECT_EQ(rl::encode_scaled_i16(0.12345, 1e4, "x"), 1235);  // 0.1 mm, nearest
  EXPECT_EQ(rl::encode_scaled_i16(-0.5, 1e4, "x"), static_cast<std::uint16_t>(-5000));
  EXPECT_EQ(rl::encode_scaled_i16(3.2767, 1e4, "x"), 32767);
  EXPECT_EQ(rl::encode_scaled_i16(-3.2768, 1e4, "x"), 0x8000);
  EXPECT_THROW(rl::encode_scaled_i16(3.27685, 1e4, "x"), rl::EncodingError);
  EXPECT_THROW(rl::encode_scaled_i16(std::nan(""), 1e4, "x"), rl::EncodingError);
  try {
    rl::encode_scaled_i16(4.0, 1e4, "target z");
    FAIL();
  } catch (const rl::EncodingError& e) {
    EXPECT_NE(std::string(e.what()).find("target z"), std::string::npos);
  }
}

TEST(PoseRegisters, GoldenEncoding) {
  // Tool 0.4 m forward, -0.25 m left, 0.5 m up, pointing down (rotation pi about x).
  const auto T =
      dentmark::make_transform_rotvec(Eigen::Vector3d(3.0, 0.0, 0.0), Eigen::Vector3d(0.4, -0.25, 0.5));
  std::array<std::uint16_t, 6> r{};
  rl::encode_pose(T, r);
  EXPECT_EQ(r[0], 4000);
  EXPECT_EQ(r[1], static_cast<std::uint16_t>(-2500));
  EXPECT_EQ(r[2], 5000);
  EXPECT_EQ(r[3], 3000);
  EXPECT_EQ(r[4], 0);
  EXPECT_EQ(r[5], 0);
}

TEST(PoseRegisters, RoundTripWithinQuantisation) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> pos(-3.0, 3.0), ang(-1.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    Eigen::Vector3d rv(ang(rng), ang(rng), ang(rng));
    rv *= 3.0 / std::max(1.0, rv.norm());
    const auto T = dentmark::make_transform_rotvec(rv, Eigen::Vector3d(pos(rng), pos(rng), pos(rng)));
    std::array<std::uint16_t, 6> r{};
    rl::encode_pose(T, r);
    const auto back = rl::decode_pose(r);
    // Half a unit per axis: 0.05 mm per coordinate, 0.5 mrad per rotation-vector component.
    EXPECT_LE((back.translation() - T.translation()).cwiseAbs().maxCoeff(), 0.5e-4 + 1e-12);
    EXPECT_LE(dentmark::rotation_angle_between(back, T), std::sqrt(3.0) * 0.5e-3 * 1.01);
  }
}

TEST(PoseRegisters, OutOfRangeLeavesRegistersUntouched) {
  std::array<std::uint16_t, 6> r{1, 2, 3, 4, 5, 6};
  const auto T = dentmark::make_transform_rotvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 5.0, 0.1));
  EXPECT_THROW(rl::encode_pose(T, r), rl::EncodingError);
  EXPECT_EQ(r, (std::array<std::uint16_t, 6>{1, 2, 3, 4, 5, 6}));
}

TEST(RegisterMap, FaultNames) {
  EXPECT_EQ(rl::fault_names(0), "none");
  EXPECT_EQ(rl::fault_names(rl::fault::kWorkspace | rl::fault::kHeartbeatLost), "workspace|heartbeat_lost");
  EXPECT_EQ(rl::fault_names(0x8001), "workspace|0x8000");
}
