// drive.json manifests: the whole drive loader (files it names mostly do not exist, which must be
// refused cleanly), the calibration reader and the input list used by output checks.
#include <cstdint>
#include <string>

#include "epiloc/core/error.h"
#include "epiloc/io/drive.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = epiloc::fuzz::WriteInput("drive.json", data, size);
  const std::string dir = epiloc::fuzz::ScratchDir().string();
  (void)epiloc::DriveInputPaths(dir);
  try {
    (void)epiloc::ReadCalibrationFile(path);
  } catch (const epiloc::Error&) {
  }
  try {
    (void)epiloc::LoadDrive(dir);
  } catch (const epiloc::Error&) {
  }
  return 0;
}
