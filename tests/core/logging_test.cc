#include "epiloc/core/logging.h"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <string>

namespace epiloc {
namespace {

// Issue 18 (unseen inputs): a drive name holding ESC [31m and a line break (from drive.json or a
// database) went raw into a warning: two lines on stderr, and the terminal turned red.
TEST(Logging, ControlBytesInAWarningAreEscaped) {
  InitLogging(Verbosity::kNormal);
  ::testing::internal::CaptureStderr();
  spdlog::warn("survey drive '{}' is incomplete", "x\x1b[31m\ny");
  spdlog::default_logger()->flush();
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(err, "[warning] survey drive 'x\\x1b[31m\\x0ay' is incomplete\n");
}

}  // namespace
}  // namespace epiloc
