#include "epiloc/survey/db_info.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

namespace epiloc {
namespace {

// Issue 18 (unseen inputs): a drive named "evil\x1b[2J\nname" in drive.json went raw into `epiloc
// info`: the line split in two and the terminal was cleared.
TEST(FormatDatabaseInfo, ControlBytesOfADriveNameAreEscaped) {
  DatabaseInfo info;
  DriveInfo drive;
  drive.name = "evil\x1b[2J\nname";
  drive.positions = "gnss\r";
  drive.num_frames = 3;
  drive.num_frames_planned = 3;
  drive.complete = true;
  info.drives.push_back(drive);
  const std::string text = FormatDatabaseInfo(info);
  EXPECT_THAT(text, ::testing::HasSubstr("  evil\\x1b[2J\\x0aname: 3 frames"));
  EXPECT_THAT(text, ::testing::HasSubstr("positions from gnss\\x0d\n"));
  EXPECT_EQ(text.find('\x1b'), std::string::npos);
}

}  // namespace
}  // namespace epiloc
