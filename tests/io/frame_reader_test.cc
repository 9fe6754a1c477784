#include "epiloc/io/frame_reader.h"

#include <sys/stat.h>

#include <fstream>
#include <iterator>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "epiloc/core/hash.h"
#include "io_test_util.h"

namespace epiloc {
namespace {

constexpr int kWidth = 40;
constexpr int kHeight = 30;

Drive ImageDrive(const TempDir& dir, const std::vector<std::string>& images) {
  Drive drive;
  drive.dir = dir.str();
  drive.camera.width = kWidth;
  drive.camera.height = kHeight;
  drive.camera.fx = drive.camera.fy = 40;
  drive.camera.cx = 19.5;
  drive.camera.cy = 14.5;
  for (size_t i = 0; i < images.size(); ++i) {
    drive.frames.push_back({static_cast<frame_t>(i), i * 0.1, images[i]});
  }
  return drive;
}

double MaxDifference(const cv::Mat& a, const cv::Mat& b) {
  EXPECT_EQ(a.size(), b.size());
  EXPECT_EQ(a.type(), b.type());
  if (a.size() != b.size() || a.type() != b.type()) return 1e9;
  return cv::norm(a, b, cv::NORM_INF);
}

TEST(FrameReader, ReadsGreyAndColourPngAndJpeg) {
  TempDir dir;
  const cv::Mat grey = Pattern(kWidth, kHeight, CV_8UC1, 1);
  const cv::Mat colour = Pattern(kWidth, kHeight, CV_8UC3, 2);
  WriteImage(dir / "grey.png", grey);
  WriteImage(dir / "colour.png", colour);
  WriteImage(dir / "grey.jpg", grey);
  WriteImage(dir / "colour.jpeg", colour);
  const FrameReader reader(
      ImageDrive(dir, {"grey.png", "colour.png", "grey.jpg", dir / "colour.jpeg"}));
  ASSERT_EQ(reader.size(), 4u);

  EXPECT_EQ(MaxDifference(reader.ReadGrey(0), grey), 0);
  cv::Mat grey_as_colour;
  cv::cvtColor(grey, grey_as_colour, cv::COLOR_GRAY2BGR);
  EXPECT_EQ(MaxDifference(reader.ReadColour(0), grey_as_colour), 0);

  EXPECT_EQ(MaxDifference(reader.ReadColour(1), colour), 0);
  cv::Mat colour_as_grey;
  cv::cvtColor(colour, colour_as_grey, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(MaxDifference(reader.ReadGrey(1), colour_as_grey), 0);

  // JPEG is lossy and the pattern has sharp edges: compare on average, against another pattern too.
  const cv::Mat jpeg_grey = reader.ReadGrey(2);
  ASSERT_EQ(jpeg_grey.type(), CV_8UC1);
  EXPECT_LT(cv::norm(jpeg_grey, grey, cv::NORM_L1) / grey.total(), 25.0);
  EXPECT_GT(cv::norm(jpeg_grey, Pattern(kWidth, kHeight, CV_8UC1, 5), cv::NORM_L1) / grey.total(),
            60.0);
  const cv::Mat jpeg_colour = reader.ReadColour(3);
  ASSERT_EQ(jpeg_colour.type(), CV_8UC3);
  EXPECT_LT(cv::norm(jpeg_colour, colour, cv::NORM_L1) / colour.total() / 3, 25.0);
}

TEST(FrameReader, ConvertsSixteenBitToEightBit) {
  TempDir dir;
  WriteImage(dir / "grey16.png", Pattern(kWidth, kHeight, CV_16UC1, 3));
  WriteImage(dir / "colour16.png", Pattern(kWidth, kHeight, CV_16UC3, 4));
  const FrameReader reader(ImageDrive(dir, {"grey16.png", "colour16.png"}));
  // Pattern stores value * 256 + 77; 8 bit keeps the high byte.
  EXPECT_EQ(MaxDifference(reader.ReadGrey(0), Pattern(kWidth, kHeight, CV_8UC1, 3)), 0);
  EXPECT_EQ(MaxDifference(reader.ReadColour(1), Pattern(kWidth, kHeight, CV_8UC3, 4)), 0);
  EXPECT_EQ(reader.ReadGrey(1).type(), CV_8UC1);
}

TEST(FrameReader, ReportsMissingCorruptAndWrongSizeImages) {
  TempDir dir;
  WriteImage(dir / "small.png", Pattern(kWidth - 2, kHeight, CV_8UC1));
  WriteText(dir / "corrupt.png", "this is not a PNG");
  const FrameReader reader(ImageDrive(dir, {"absent.png", "corrupt.png", "small.png"}));
  ExpectError([&] { reader.ReadGrey(0); }, {dir / "absent.png: image file not found"});
  ExpectError([&] { reader.ReadColour(1); }, {dir / "corrupt.png: cannot decode"});
  ExpectError([&] { reader.ReadGrey(2); }, {dir / "small.png", "38x30", "40x30"});
  ExpectError([&] { reader.ReadGrey(3); }, {"out of range"});
}

// A truncated PNG or JPEG is reported in one line without the decoder libraries printing on
// stderr; a folder or FIFO given as an image is named as such, not "not found".
TEST(FrameReader, TruncatedImagesFoldersAndFifos) {
  TempDir dir;
  WriteImage(dir / "full.png", Pattern(kWidth, kHeight, CV_8UC1));
  WriteImage(dir / "full.jpg", Pattern(kWidth, kHeight, CV_8UC3));
  std::ifstream png_in(dir / "full.png", std::ios::binary);
  const std::string png((std::istreambuf_iterator<char>(png_in)), std::istreambuf_iterator<char>());
  std::ifstream jpg_in(dir / "full.jpg", std::ios::binary);
  const std::string jpg((std::istreambuf_iterator<char>(jpg_in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(ImageTruncation(png), "");
  EXPECT_EQ(ImageTruncation(jpg), "");
  EXPECT_EQ(ImageTruncation(jpg + std::string(16, '\0')), "");  // padded
  EXPECT_THAT(ImageTruncation(png.substr(0, png.size() / 2)), ::testing::HasSubstr("truncated PNG"));
  EXPECT_THAT(ImageTruncation(png.substr(0, png.size() - 12)), ::testing::HasSubstr("IEND"));
  EXPECT_THAT(ImageTruncation(jpg.substr(0, jpg.size() - 100)),
              ::testing::HasSubstr("truncated JPEG"));
  EXPECT_EQ(ImageTruncation("P5 not a png"), "");  // other formats are left to the decoder

  WriteText(dir / "half.png", png.substr(0, png.size() / 2));
  const Camera camera = ImageDrive(dir, {}).camera;
  ::testing::internal::CaptureStderr();
  ExpectError([&] { ReadImageFile(dir / "half.png", camera, false); },
              {dir / "half.png", "truncated PNG"});
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  std::filesystem::create_directories(dir / "folder.png");
  ExpectError([&] { ReadImageFile(dir / "folder.png", camera, false); }, {"is a folder"});
  ASSERT_EQ(::mkfifo((dir / "fifo.png").c_str(), 0600), 0);
  ExpectError([&] { ReadImageFile(dir / "fifo.png", camera, false); }, {"FIFO"});
  ExpectError([&] { ReadImageFile(dir / "absent.png", camera, false); }, {"not found"});

  // Issue 18 (unseen inputs): a PNG whose header declares 60000x60000 pixels made OpenCV throw
  // "OpenCV(4.6.0) .../loadsave.cpp:77: error: (-215:Assertion failed) pixels <= ..." without the
  // file's name.
  std::string bomb = png;
  for (int i = 0; i < 2; ++i) {  // width and height, big-endian, after "\x89PNG\r\n\x1a\n" + IHDR
    bomb[16 + 4 * i] = 0;
    bomb[17 + 4 * i] = 0;
    bomb[18 + 4 * i] = static_cast<char>(60000 >> 8);
    bomb[19 + 4 * i] = static_cast<char>(60000 & 0xff);
  }
  uint32_t crc = 0xffffffffu;  // CRC-32 of the IHDR chunk's type and data
  for (size_t i = 12; i < 29; ++i) {
    crc ^= static_cast<uint8_t>(bomb[i]);
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  crc ^= 0xffffffffu;
  for (int i = 0; i < 4; ++i) bomb[29 + i] = static_cast<char>(crc >> (24 - 8 * i));
  WriteText(dir / "bomb.png", bomb);
  const std::string message = ErrorOf([&] { ReadImageFile(dir / "bomb.png", camera, false); });
  EXPECT_THAT(message, ::testing::HasSubstr(dir / "bomb.png: cannot decode"));
  EXPECT_THAT(message, ::testing::Not(::testing::HasSubstr("\n")));
}

// Issue 18 item 10: a frame listed in frames.csv is named by its line there and its image name as
// listed, in one line (the decoders print nothing), whatever is wrong with the file.
TEST(FrameReader, ErrorsNameTheFramesCsvLine) {
  TempDir dir;
  WriteImage(dir / "full.png", Pattern(kWidth, kHeight, CV_8UC1));
  std::ifstream png_in(dir / "full.png", std::ios::binary);
  const std::string png((std::istreambuf_iterator<char>(png_in)), std::istreambuf_iterator<char>());
  WriteText(dir / "half.png", png.substr(0, png.size() / 2));
  WriteText(dir / "garbage.png", "this is not a PNG");
  WriteImage(dir / "small.png", Pattern(kWidth - 2, kHeight, CV_8UC1));
  Drive drive = ImageDrive(dir, {"full.png", "half.png", "garbage.png", "absent.png", "small.png"});
  drive.frames_csv = dir / "frames.csv";
  for (size_t i = 0; i < drive.frames.size(); ++i)
    drive.frames[i].line = static_cast<int64_t>(i) + 2;
  const FrameReader reader(drive);
  EXPECT_EQ(MaxDifference(reader.ReadGrey(0), Pattern(kWidth, kHeight, CV_8UC1)), 0);
  ::testing::internal::CaptureStderr();
  ExpectError([&] { reader.ReadGrey(1); },
              {dir / "frames.csv:3: image half.png: cannot decode (truncated PNG: "});
  ExpectError([&] { reader.ReadColour(2); },
              {dir / "frames.csv:4: image garbage.png: cannot decode"});
  ExpectError([&] { reader.ReadGrey(3); },
              {dir / "frames.csv:5: image absent.png: image file not found"});
  ExpectError([&] { reader.ReadGrey(4); },
              {dir / "frames.csv:6: image small.png: image size 38x30 differs"});
  // The same through ReadFrameImage (frames polled from a growing drive).
  ExpectError([&] { ReadFrameImage(drive, drive.frames[1], false); },
              {dir / "frames.csv:3: image half.png: cannot decode (truncated PNG: "});
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  // Frames not from a CSV (a folder) are named by their file.
  drive.frames_csv.clear();
  ExpectError([&] { FrameReader(drive).ReadGrey(1); },
              {dir / "half.png: cannot decode (truncated PNG: "});
}

TEST(FrameReader, ContentHashIsTheFileHash) {
  TempDir dir;
  WriteImage(dir / "a.png", Pattern(kWidth, kHeight, CV_8UC1, 1));
  WriteImage(dir / "b.png", Pattern(kWidth, kHeight, CV_8UC1, 2));
  const Drive drive = ImageDrive(dir, {"a.png", "b.png"});
  EXPECT_EQ(FrameContentHash(drive, 0), HashFile(dir / "a.png"));
  EXPECT_EQ(FrameContentHash(drive, 0).size(), 32u);
  EXPECT_NE(FrameContentHash(drive, 0), FrameContentHash(drive, 1));
  EXPECT_EQ(FrameReader(drive).ContentHash(1), FrameContentHash(drive, 1));
}

class VideoTest : public ::testing::Test {
 protected:
  static constexpr int kFrames = 60;

  void SetUp() override {
    cv::VideoWriter writer(dir_ / "drive.avi", cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0,
                           cv::Size(kWidth, kHeight), true);
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < kFrames; ++i) writer.write(Pattern(kWidth, kHeight, CV_8UC3, i));
    writer.release();
    drive_ = ImageDrive(dir_, std::vector<std::string>(kFrames, ""));
    drive_.video = "drive.avi";
    // The decoded frames in order, as reference.
    cv::VideoCapture capture(dir_ / "drive.avi");
    cv::Mat frame;
    while (capture.read(frame)) reference_.push_back(frame.clone());
    ASSERT_EQ(reference_.size(), static_cast<size_t>(kFrames));
  }

  TempDir dir_;
  Drive drive_;
  std::vector<cv::Mat> reference_;
};

TEST_F(VideoTest, ReadsInOrderBackwardsAndWithJumps) {
  const FrameReader reader(drive_);
  for (const size_t i : {0, 1, 2, 5, 3, 40, 41, 10, 59, 0}) {
    EXPECT_EQ(MaxDifference(reader.ReadColour(i), reference_[i]), 0) << "frame " << i;
  }
  cv::Mat grey;
  cv::cvtColor(reference_[7], grey, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(MaxDifference(reader.ReadGrey(7), grey), 0);
  // The decoded frame is close to what was written (MJPG is lossy).
  EXPECT_LT(cv::norm(reader.ReadColour(12), Pattern(kWidth, kHeight, CV_8UC3, 12), cv::NORM_L1) /
                (kWidth * kHeight * 3),
            25.0);
  EXPECT_EQ(reader.ContentHash(3), FrameContentHash(drive_, 3));
  EXPECT_NE(reader.ContentHash(3), reader.ContentHash(4));
}

TEST_F(VideoTest, WrongSizeAndMissingFrame) {
  Drive wrong = drive_;
  wrong.camera.width = kWidth * 2;
  wrong.camera.cx = kWidth;
  ExpectError([&] { FrameReader(wrong).ReadGrey(0); }, {dir_ / "drive.avi", "40x30", "80x30"});
  Drive longer = drive_;
  longer.frames.push_back({kFrames + 5, 99.0, ""});
  ExpectError([&] { FrameReader(longer).ReadGrey(kFrames); }, {dir_ / "drive.avi", "cannot read"});
}

TEST_F(VideoTest, ConcurrentReadsMatchSequentialOnes) {
  // Image files and the video, read from four threads in different orders.
  std::vector<std::string> images;
  for (int i = 0; i < 20; ++i) {
    images.push_back(fmt::format("f{}.png", i));
    WriteImage(dir_ / images.back(), Pattern(kWidth, kHeight, CV_8UC3, i));
  }
  const FrameReader image_reader(ImageDrive(dir_, images));
  const FrameReader video_reader(drive_);
  std::vector<int> failures(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int k = 0; k < 40; ++k) {
        const size_t i = static_cast<size_t>((k * (t + 3) + t * 7) % 20);
        if (cv::norm(image_reader.ReadColour(i),
                     Pattern(kWidth, kHeight, CV_8UC3, static_cast<int>(i)), cv::NORM_INF) != 0) {
          ++failures[t];
        }
        const size_t v = static_cast<size_t>((k * (t + 1) + t * 11) % kFrames);
        if (cv::norm(video_reader.ReadColour(v), reference_[v], cv::NORM_INF) != 0) ++failures[t];
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(failures, std::vector<int>(4, 0));
}

}  // namespace
}  // namespace epiloc
