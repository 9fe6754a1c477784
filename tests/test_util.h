// Helpers shared by the test suites: a temporary directory, text files and expectations on
// epiloc::Error messages.
#pragma once

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {

#ifdef EPILOC_SHARED_DATA_DIR
// The shared KITTI raw drive (2011_09_26, drive 0005) the real-data tests read, beside the
// checkout (../shared/data); those tests skip when it is absent (EPILOC_SKIP_UNLESS_EXISTS).
inline std::filesystem::path KittiRawDrive() {
  return std::filesystem::path(EPILOC_SHARED_DATA_DIR) / "kitti_raw" / "2011_09_26" /
         "2011_09_26_drive_0005_sync";
}

// Skips the running test when `path` (shared real data) does not exist.
#define EPILOC_SKIP_UNLESS_EXISTS(path)                                             \
  do {                                                                              \
    if (!std::filesystem::exists(path)) {                                           \
      GTEST_SKIP() << (path) << " not found (real-data test needs ../shared/data)"; \
    }                                                                               \
  } while (0)
#endif  // EPILOC_SHARED_DATA_DIR

// Whether this build runs under AddressSanitizer (it reserves terabytes of shadow memory and
// holds freed blocks in a quarantine: memory limits and resident-memory bounds do not apply).
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

// A fresh directory named after the running test, removed when the object goes away.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = std::string("epiloc_") +
                             (info ? std::string(info->test_suite_name()) + "_" + info->name()
                                   : std::string("test")) +
                             "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
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

// Writes `text` to `path`, creating its directory.
inline void WriteText(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream out(path);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

// The message of the epiloc::Error `function` throws ("" and a test failure if none).
template <typename Function>
std::string ErrorOf(Function&& function) {
  try {
    function();
  } catch (const Error& error) {
    return error.what();
  }
  ADD_FAILURE() << "no epiloc::Error thrown";
  return "";
}

// Runs `function` and expects an epiloc::Error whose message contains every one of `parts`.
template <typename Function>
void ExpectError(Function&& function, const std::vector<std::string>& parts) {
  const std::string message = ErrorOf(function);
  for (const std::string& part : parts) {
    EXPECT_THAT(message, ::testing::HasSubstr(part)) << "message: " << message;
  }
}

// A drive directory another program is still writing: `source`'s manifest and images (linked),
// frames.csv and gnss.csv with their header rows only; the test appends rows to `frames` and
// `gnss` (flushing each) as a recorder would.
struct GrowingDrive {
  GrowingDrive(const std::filesystem::path& source, const std::filesystem::path& dir)
      : dir(dir) {
    std::filesystem::create_directories(dir);
    std::filesystem::copy_file(source / "drive.json", dir / "drive.json");
    std::filesystem::create_directory_symlink(source / "images", dir / "images");
    frames.open(dir / "frames.csv");
    frames << "frame,timestamp_s,image\n" << std::flush;
    gnss.open(dir / "gnss.csv");
    gnss << "timestamp_s,lat_deg,lon_deg,alt_m\n" << std::flush;
  }
  std::filesystem::path dir;
  std::ofstream frames;
  std::ofstream gnss;
};

}  // namespace epiloc
