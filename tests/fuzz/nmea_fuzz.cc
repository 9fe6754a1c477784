// NMEA logs (with and without a given date) and timestamp files.
#include <cstdint>
#include <string>

#include "epiloc/core/error.h"
#include "epiloc/io/position_readers.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = epiloc::fuzz::WriteInput("input.nmea", data + 1, size - 1);
  try {
    switch (data[0] % 3) {
      case 0:
        (void)epiloc::ReadNmea(path, "");
        break;
      case 1:
        (void)epiloc::ReadNmea(path, "2024-02-29");
        break;
      case 2:
        (void)epiloc::ReadTimestamps(path);
        break;
    }
  } catch (const epiloc::Error&) {
  }
  return 0;
}
