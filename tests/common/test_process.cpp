// process::run: exit codes, both output streams, a missing program, a hung one killed.
#include <gtest/gtest.h>

#include "dentmark/common/process.h"

namespace dentmark::process {
namespace {

TEST(Process, CollectsBothStreamsAndTheExitCode) {
  const Result r = run({"sh", "-c", "echo out; echo err >&2; exit 3"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.output.find("out\n"), std::string::npos);
  EXPECT_NE(r.output.find("err\n"), std::string::npos);
  EXPECT_FALSE(r.timed_out);
}

TEST(Process, StdinIsEmptySoNothingWaitsOnIt) {
  const Result r = run({"cat"}, 10.0);
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.output, "");
  EXPECT_FALSE(r.timed_out);
}

TEST(Process, AMissingProgramIsAnErrorNamingIt) {
  try {
    run({"dentmark-no-such-tool", "x"});
    FAIL() << "no error";
  } catch (const ProcessError& e) {
    EXPECT_NE(std::string(e.what()).find("dentmark-no-such-tool"), std::string::npos) << e.what();
  }
}

TEST(Process, AHungProgramIsKilledAtTheTimeout) {
  const Result r = run({"sh", "-c", "echo started; exec sleep 60"}, 0.5);
  EXPECT_TRUE(r.timed_out);
  EXPECT_EQ(r.exit_code, 128 + 9);
  EXPECT_NE(r.output.find("started"), std::string::npos);
}

}  // namespace
}  // namespace dentmark::process
