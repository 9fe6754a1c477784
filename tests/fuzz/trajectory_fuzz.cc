// Trajectory files: TUM and KITTI poses (with and without a times file and rotation check).
#include <cstdint>
#include <string>

#include "epiloc/core/error.h"
#include "epiloc/io/pose_files.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = epiloc::fuzz::WriteInput("trajectory.txt", data + 1, size - 1);
  try {
    switch (data[0] % 4) {
      case 0:
        (void)epiloc::ReadTumPoses(path);
        break;
      case 1:
        (void)epiloc::ReadKittiPoses(path);
        break;
      case 2: {
        // The same bytes as poses and as their times file.
        (void)epiloc::ReadKittiPoses(path, path, false);
        break;
      }
      case 3:
        (void)epiloc::ReadKittiPoses(path, "", false);
        break;
    }
  } catch (const epiloc::Error&) {
  }
  return 0;
}
