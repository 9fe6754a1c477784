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
#include "test_util.h"

namespace epiloc {


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


}  // namespace epiloc
