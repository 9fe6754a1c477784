// Point-cloud files: PLY (ascii / binary, lists), PCD (ascii / binary / binary_compressed with
// LZF), LAS, KITTI .bin and XYZ. The first byte picks the format (by the file's extension).
#include <cstdint>
#include <string>

#include "epiloc/cloud/cloud_io.h"
#include "epiloc/core/error.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kExtensions[] = {".ply", ".pcd", ".las", ".bin", ".xyz"};
  const std::string path =
      epiloc::fuzz::WriteInput(std::string("cloud") + kExtensions[data[0] % 5], data + 1, size - 1);
  try {
    (void)epiloc::ReadPointCloudHeader(path);
  } catch (const epiloc::Error&) {
  }
  try {
    (void)epiloc::ReadPointCloud(path);
  } catch (const epiloc::Error&) {
  }
  return 0;
}
