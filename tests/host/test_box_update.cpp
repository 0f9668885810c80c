// dentmark update's reading of the box: RAUC's status JSON (as RAUC 1.8 prints it) and
// the verdict from it and the health units' states.
#include <gtest/gtest.h>

#include "dentmark/host/update/box_update.h"

namespace dentmark::update {
namespace {

// `rauc status --detailed --output-format=json` of a box booted from A that has just
// installed into B (B primary), shortened to the fields RAUC always prints.
const char* kInstalled = R"({
  "compatible": "dentmark-qemu-virt-aarch64", "variant": "", "booted": "A", "boot_primary": "rootfs.1",
  "slots": [
    {"rootfs.1": {"class": "rootfs", "device": "/dev/vda3", "type": "ext4", "bootname": "B",
                  "state": "inactive", "parent": null, "mountpoint": null, "boot_status": "good"}},
    {"rootfs.0": {"class": "rootfs", "device": "/dev/vda2", "type": "ext4", "bootname": "A",
                  "state": "booted", "parent": null, "mountpoint": "/", "boot_status": "good"}}
  ]})";

std::string booted_b(const char* boot_status) {
  return std::string(R"({"compatible": "c", "booted": "B", "boot_primary": "rootfs.1", "slots": [
    {"rootfs.0": {"bootname": "A", "state": "inactive", "boot_status": "good"}},
    {"rootfs.1": {"bootname": "B", "state": "booted", "boot_status": ")") +
         boot_status + R"("}}]})";
}

TEST(RaucStatus, ReadsSlotsAndThePrimary) {
  const RaucStatus s = parse_rauc_status(kInstalled);
  EXPECT_EQ(s.compatible, "dentmark-qemu-virt-aarch64");
  EXPECT_EQ(s.boot_primary, "rootfs.1");
  ASSERT_EQ(s.slots.size(), 2u);
  ASSERT_TRUE(s.booted());
  EXPECT_EQ(s.booted()->name, "rootfs.0");
  EXPECT_EQ(s.booted()->bootname, "A");
}

TEST(RaucStatus, BrokenJsonNamesWhatIsWrong) {
  const auto error_of = [](const std::string& json) {
    try {
      parse_rauc_status(json);
    } catch (const UpdateError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("rauc: command not found").find("not JSON"), std::string::npos);
  EXPECT_NE(error_of(R"({"compatible": "c", "slots": []})").find("boot_primary"), std::string::npos);
  EXPECT_NE(error_of(R"({"compatible": "c", "boot_primary": "rootfs.0"})").find("slots"), std::string::npos);
  EXPECT_NE(error_of(R"({"compatible": "c", "boot_primary": "x", "slots": [{"rootfs.0": {"state": 3}}]})")
                .find("slot rootfs.0"),
            std::string::npos);
}

TEST(UpdateVerdict, NewSlotGoodAndHealthyIsUpdated) {
  const RaucStatus s = parse_rauc_status(booted_b("good"));
  EXPECT_EQ(judge(s, "rootfs.0", "rootfs.1", {"active", "active"}), Verdict::kUpdated);
}

TEST(UpdateVerdict, NewSlotStillCheckingIsWaiting) {
  const RaucStatus s = parse_rauc_status(booted_b(""));
  EXPECT_EQ(judge(s, "rootfs.0", "rootfs.1", {"activating", "inactive"}), Verdict::kWaiting);
  // Healthy units but RAUC has not marked it good yet: not done.
  EXPECT_EQ(judge(s, "rootfs.0", "rootfs.1", {"active", "active"}), Verdict::kWaiting);
  EXPECT_EQ(judge(s, "rootfs.0", "rootfs.1", {}), Verdict::kWaiting);
}

TEST(UpdateVerdict, AFailedHealthCheckOnTheNewSlotIsBad) {
  const RaucStatus s = parse_rauc_status(booted_b(""));
  EXPECT_EQ(judge(s, "rootfs.0", "rootfs.1", {"failed", "inactive"}), Verdict::kNewSlotBad);
}

TEST(UpdateVerdict, TheOldSlotAgainIsARollback) {
  const RaucStatus s = parse_rauc_status(kInstalled);  // rootfs.0 booted
  EXPECT_EQ(judge(s, "rootfs.0", "rootfs.1", {"active", "active"}), Verdict::kRolledBack);
}

}  // namespace
}  // namespace dentmark::update
