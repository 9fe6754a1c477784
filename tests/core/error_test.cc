#include "epiloc/core/error.h"

#include <gtest/gtest.h>

namespace epiloc {
namespace {

TEST(Printable, EscapesControlBytesFromInputFiles) {
  // A TUM line with a terminal "clear screen" sequence must not reach the terminal as is.
  EXPECT_EQ(Printable("ab\x1b[2Jc\n\t"), "ab\\x1b[2Jc\\x0a\\x09");
  EXPECT_EQ(Printable("caf\xC3\xA9 1.5"), "caf\xC3\xA9 1.5");  // UTF-8 stays readable
  EXPECT_EQ(Printable(std::string("a\0b", 3)), "a\\x00b");
  EXPECT_EQ(Printable("abcdef", 3), "abc...");
}

}  // namespace
}  // namespace epiloc
