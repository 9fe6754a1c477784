// Helpers of the io tests: a temporary directory, small text files and images.
#pragma once

#include <unistd.h>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "epiloc/core/error.h"

namespace epiloc {

// A fresh directory removed when the object goes away.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = std::string("epiloc_io_") + (info ? info->name() : "test") + "_" +
                             std::to_string(::getpid()) + "_" + std::to_string(counter++);
    path_ = std::filesystem::temp_directory_path() / name;
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code error;
    std::filesystem::remove_all(path_, error);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  std::string str() const { return path_.string(); }
  // dir/name as a string.
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

inline void WriteText(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream out(path);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

// A deterministic test pattern: value depends on (x, y, channel, seed).
inline cv::Mat Pattern(int width, int height, int type, int seed = 0) {
  cv::Mat image(height, width, type);
  const int channels = image.channels();
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int value = (x * 7 + y * 13 + c * 50 + seed * 31) % 256;
        if (image.depth() == CV_16U) {
          image.ptr<uint16_t>(y)[x * channels + c] = static_cast<uint16_t>(value * 256 + 77);
        } else {
          image.ptr<uint8_t>(y)[x * channels + c] = static_cast<uint8_t>(value);
        }
      }
    }
  }
  return image;
}

inline void WriteImage(const std::string& path, const cv::Mat& image) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  ASSERT_TRUE(cv::imwrite(path, image)) << path;
}

// Runs `f` and expects an epiloc::Error whose message contains every one of `parts`.
template <typename F>
void ExpectError(F&& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no Error thrown, expected one containing '" << parts.front() << "'";
  } catch (const Error& e) {
    for (const auto& part : parts) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr(part)) << "message: " << e.what();
    }
  }
}

}  // namespace epiloc
