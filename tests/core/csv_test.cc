#include "epiloc/core/csv.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "epiloc/core/error.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

class CsvFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           fmt::format("epiloc_csv_test_{}_{}_{}", getpid(),
                       info->test_suite_name(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Write(const std::string& name, const std::string& text) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }

  fs::path dir_;
};


// Issue 18 (unseen inputs): a file without line breaks (/dev/zero as a frames CSV or --config, a
// binary file) was read into one std::string until memory ran out (16 GB before the 60 s
// timeout). Lines are bounded; the message names the file and line, and quotes none of it.
TEST(ReadLine, ALineBeyondTheBoundIsAnErrorNotAllMemory) {
  TempDir dir;
  const std::string path = dir / "frames.csv";
  WriteText(path, "frame,timestamp_s,image\n0,0," + std::string(kMaxLineBytes + 10, 'x'));
  const std::string message = ErrorOf([&] {
    CsvReader csv(path);
    while (csv.Next()) {
    }
  });
  EXPECT_THAT(message, ::testing::HasSubstr(path + ":2: line longer than"));
  EXPECT_LT(message.size(), 400u);
  if (fs::exists("/dev/zero")) {
    ExpectError([] { CsvReader csv("/dev/zero"); }, {"/dev/zero:1: line longer than"});
  }
}

// Issue 18 (unseen inputs): "1,0.1,images/000001.png\0junk" read images/000001.png, exit 0.
TEST(CsvReader, ANulByteInALineIsAnError) {
  TempDir dir;
  const std::string path = dir / "frames.csv";
  WriteText(path, std::string("frame,timestamp_s,image\n1,0.1,images/1.png\0junk\n", 48));
  ExpectError(
      [&] {
        CsvReader csv(path);
        while (csv.Next()) {
        }
      },
      {path + ":2: a NUL byte"});
}

TEST(ReadLine, BehavesAsGetlineOtherwise) {
  std::istringstream in("a\n\nlast");
  std::string line;
  ASSERT_TRUE(ReadLine(in, line, "x", 1));
  EXPECT_EQ(line, "a");
  ASSERT_TRUE(ReadLine(in, line, "x", 2));
  EXPECT_EQ(line, "");
  ASSERT_TRUE(ReadLine(in, line, "x", 3));
  EXPECT_EQ(line, "last");
  EXPECT_TRUE(in.eof());
  EXPECT_FALSE(ReadLine(in, line, "x", 4));
  EXPECT_TRUE(in.fail());
  std::istringstream exact(std::string(kMaxLineBytes, 'y') + "\n");
  ASSERT_TRUE(ReadLine(exact, line, "x", 1));
  EXPECT_EQ(line.size(), kMaxLineBytes);
}

TEST(SplitCsvLine, HandlesQuotesAndEmptyFields) {
  EXPECT_THAT(SplitCsvLine("a,b,c"), ElementsAre("a", "b", "c"));
  EXPECT_THAT(SplitCsvLine(" a , b ,c "), ElementsAre("a", "b", "c"));
  EXPECT_THAT(SplitCsvLine("\"a,b\",\"say \"\"hi\"\"\",\"\""),
              ElementsAre("a,b", "say \"hi\"", ""));
  EXPECT_THAT(SplitCsvLine("1,,3,"), ElementsAre("1", "", "3", ""));
  EXPECT_THAT(SplitCsvLine(""), ElementsAre(""));
  EXPECT_THAT(SplitCsvLine("x,y\r"), ElementsAre("x", "y"));
}

TEST(SplitCsvLine, QuotedFieldsKeepTheirSpaces) {
  EXPECT_THAT(SplitCsvLine(" \" a \" ,b"), ElementsAre(" a ", "b"));
  EXPECT_THAT(SplitCsvLine("\"x\"  "), ElementsAre("x"));
}

TEST(Trim, RemovesWhiteSpaceAtBothEnds) {
  EXPECT_EQ(Trim("  a b \t\r\n"), "a b");
  EXPECT_EQ(Trim(" \t "), "");
  EXPECT_EQ(Trim(""), "");
}

TEST(ParseDouble, AcceptsFiniteNumbers) {
  EXPECT_EQ(ParseDouble("1.5", "here"), 1.5);
  EXPECT_EQ(ParseDouble(" -2.5e-3 ", "here"), -2.5e-3);
  EXPECT_EQ(ParseDouble("42", "here"), 42.0);
  EXPECT_EQ(ParseDouble("49.0114951367", "here"), 49.0114951367);
}

TEST(ParseDouble, RejectsEverythingElse) {
  for (const std::string text :
       {"1.5x", "x1.5", "1.5 2", "nan", "NaN", "inf", "-inf", "Infinity",
        "1e999", "", "   ", "1,5"}) {
    SCOPED_TRACE(text);
    const std::string message =
        ErrorOf([&] { ParseDouble(text, "poses.csv:7 column 'lat'"); });
    EXPECT_THAT(message, HasSubstr("poses.csv:7 column 'lat'"));
  }
  EXPECT_THAT(ErrorOf([] { ParseDouble("1.5x", "f.csv:2"); }),
              HasSubstr("f.csv:2: '1.5x' is not a number"));
  EXPECT_THAT(ErrorOf([] { ParseDouble("nan", "f.csv:2"); }),
              HasSubstr("not a finite number"));
  EXPECT_THAT(ErrorOf([] { ParseDouble("inf", "f.csv:2"); }),
              HasSubstr("not a finite number"));
}

TEST(ParseInt, AcceptsIntegersOnly) {
  EXPECT_EQ(ParseInt("42", "here"), 42);
  EXPECT_EQ(ParseInt(" -7 ", "here"), -7);
  EXPECT_EQ(ParseInt("9223372036854775807", "here"),
            std::numeric_limits<int64_t>::max());
  for (const std::string text :
       {"1.5", "12a", "", "0x10", "99999999999999999999"}) {
    SCOPED_TRACE(text);
    EXPECT_THAT(ErrorOf([&] { ParseInt(text, "f.csv:3"); }),
                HasSubstr("f.csv:3"));
  }
}

TEST_F(CsvFileTest, ReadsRowsSkippingCommentsAndBlankLines) {
  const std::string path = Write("poses.csv",
                                 "# written by a test\n"
                                 "frame,lat,name,opt\n"
                                 "\n"
                                 "0,49.5,\"a, b\",1.25\n"
                                 "  # an indented comment\n"
                                 "1,-3e2,\"say \"\"x\"\"\",\r\n");
  CsvReader reader(path);
  EXPECT_EQ(reader.path(), path);
  EXPECT_THAT(reader.header(), ElementsAre("frame", "lat", "name", "opt"));
  EXPECT_TRUE(reader.HasColumn("lat"));
  EXPECT_FALSE(reader.HasColumn("lon"));
  reader.RequireColumns({"frame", "lat"});

  ASSERT_TRUE(reader.Next());
  EXPECT_EQ(reader.line(), 4);
  EXPECT_EQ(reader.where(), path + ":4");
  EXPECT_EQ(reader.GetInt("frame"), 0);
  EXPECT_EQ(reader.GetDouble("lat"), 49.5);
  EXPECT_EQ(reader.Get("name"), "a, b");
  EXPECT_EQ(reader.GetOptionalDouble("opt"), 1.25);
  EXPECT_FALSE(reader.GetOptionalDouble("absent").has_value());

  ASSERT_TRUE(reader.Next());
  EXPECT_EQ(reader.line(), 6);
  EXPECT_EQ(reader.GetInt("frame"), 1);
  EXPECT_EQ(reader.GetDouble("lat"), -300.0);
  EXPECT_EQ(reader.Get("name"), "say \"x\"");
  EXPECT_FALSE(reader.GetOptionalDouble("opt").has_value());

  EXPECT_FALSE(reader.Next());
}

TEST_F(CsvFileTest, AcceptsUtf8ByteOrderMark) {
  // Spreadsheets save "CSV UTF-8" with a BOM; it must not become part of the first column name.
  CsvReader reader(Write("frames.csv", "\xEF\xBB\xBF" "frame,timestamp_s\n3,1.5\n"));
  EXPECT_THAT(reader.header(), ElementsAre("frame", "timestamp_s"));
  reader.RequireColumns({"frame"});
  ASSERT_TRUE(reader.Next());
  EXPECT_EQ(reader.GetInt("frame"), 3);

  CsvReader commented(Write("gnss.csv", "\xEF\xBB\xBF# comment\nframe\n4\n"));
  EXPECT_THAT(commented.header(), ElementsAre("frame"));
  ASSERT_TRUE(commented.Next());
  EXPECT_EQ(commented.GetInt("frame"), 4);

  // Only at the start of the file: elsewhere the bytes are data.
  CsvReader later(Write("later.csv", "name\n\xEF\xBB\xBFx\n"));
  ASSERT_TRUE(later.Next());
  EXPECT_EQ(later.Get("name"), "\xEF\xBB\xBFx");
}

TEST_F(CsvFileTest, WrongFieldCountNamesFileAndLine) {
  const std::string path = Write("bad.csv", "a,b\n1,2\n# comment\n1,2,3\n");
  CsvReader reader(path);
  ASSERT_TRUE(reader.Next());
  const std::string message = ErrorOf([&] { reader.Next(); });
  EXPECT_THAT(message, HasSubstr(path + ":4"));
  EXPECT_THAT(message, HasSubstr("3 fields, the header has 2"));
}

TEST_F(CsvFileTest, BadNumberNamesFileLineAndColumn) {
  const std::string path = Write("bad.csv", "frame,lat\n\n7,49.1x\n8,\n");
  CsvReader reader(path);
  ASSERT_TRUE(reader.Next());
  EXPECT_EQ(reader.GetInt("frame"), 7);
  EXPECT_THAT(ErrorOf([&] { reader.GetDouble("lat"); }),
              HasSubstr(path + ":3 column 'lat': '49.1x' is not a number"));
  ASSERT_TRUE(reader.Next());
  EXPECT_THAT(ErrorOf([&] { reader.GetDouble("lat"); }),
              HasSubstr(path + ":4 column 'lat'"));
  EXPECT_FALSE(reader.GetOptionalDouble("lat").has_value());
}

TEST_F(CsvFileTest, MissingColumnIsNamed) {
  const std::string path = Write("cols.csv", "a,b\n1,2\n");
  CsvReader reader(path);
  EXPECT_THAT(ErrorOf([&] {
                reader.RequireColumns({"a", "timestamp"});
              }),
              HasSubstr(path + ": missing column 'timestamp'"));
  ASSERT_TRUE(reader.Next());
  EXPECT_THAT(ErrorOf([&] { reader.Get("c"); }),
              HasSubstr("missing column 'c'"));
}

TEST_F(CsvFileTest, BadFilesAndHeaders) {
  const std::string missing = (dir_ / "missing.csv").string();
  EXPECT_THAT(ErrorOf([&] { CsvReader reader(missing); }),
              HasSubstr(missing + ": cannot open"));
  const std::string empty = Write("empty.csv", "# only a comment\n\n");
  EXPECT_THAT(ErrorOf([&] { CsvReader reader(empty); }),
              HasSubstr(empty + ": empty file"));
  const std::string twice = Write("twice.csv", "a,b,a\n");
  EXPECT_THAT(ErrorOf([&] { CsvReader reader(twice); }),
              HasSubstr(twice + ":1: column 'a' appears twice"));
  const std::string blank = Write("blank.csv", "a,,b\n");
  EXPECT_THAT(ErrorOf([&] { CsvReader reader(blank); }),
              HasSubstr("empty column name"));
}

TEST_F(CsvFileTest, WriterOutputReadsBack) {
  const std::string path = (dir_ / "out.csv").string();
  const std::vector<std::vector<std::string>> rows = {
      {"plain", "with,comma", "with \"quote\""},
      {"", " padded ", "line\rbreak"}};
  {
    CsvWriter writer(path, {"x", "y", "z"});
    for (const auto& row : rows) writer.WriteRow(row);
    EXPECT_THAT(ErrorOf([&] {
                  writer.WriteRow({"1", "2"});
                }),
                HasSubstr("2 fields for 3 columns"));
    writer.Close();
  }
  CsvReader reader(path);
  EXPECT_THAT(reader.header(), ElementsAre("x", "y", "z"));
  for (const auto& row : rows) {
    ASSERT_TRUE(reader.Next());
    EXPECT_EQ(reader.Get("x"), row[0]);
    EXPECT_EQ(reader.Get("y"), row[1]);
    EXPECT_EQ(reader.Get("z"), row[2]);
  }
  EXPECT_FALSE(reader.Next());
  const std::string unwritable = (dir_ / "no" / "such.csv").string();
  EXPECT_THAT(ErrorOf([&] { CsvWriter writer(unwritable, {"a"}); }),
              HasSubstr(unwritable + ": cannot open"));
}

TEST(CsvEscape, QuotesOnlyWhenNeeded) {
  EXPECT_EQ(CsvEscape("abc"), "abc");
  EXPECT_EQ(CsvEscape("a,b"), "\"a,b\"");
  EXPECT_EQ(CsvEscape("a\"b"), "\"a\"\"b\"");
  EXPECT_EQ(CsvEscape(" a"), "\" a\"");
  EXPECT_EQ(CsvEscape(""), "");
}

TEST(FormatDouble, ShortestRoundTrip) {
  for (const double value :
       {0.1, 1.0 / 3.0, -49.0114951367, 1e-300, 123456789.125, 0.0}) {
    EXPECT_EQ(ParseDouble(FormatDouble(value), "round trip"), value);
  }
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(std::nan("")), "");
  EXPECT_EQ(FormatFixed(2.5, 2), "2.50");
  EXPECT_EQ(FormatFixed(-0.16, 1), "-0.2");
  EXPECT_EQ(FormatFixed(std::nan(""), 3), "");
}

TEST(Where, FormatsPathAndLine) {
  EXPECT_EQ(Where("a.csv", 12), "a.csv:12");
  EXPECT_EQ(Where("a.csv"), "a.csv");
  EXPECT_EQ(Where("a.csv", 0), "a.csv");
}

}  // namespace
}  // namespace epiloc
