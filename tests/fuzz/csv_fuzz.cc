// The CSV readers: the generic reader (every field as a number), result CSVs, position CSVs
// (lat/lon and local x/y/z), frames CSVs and LiDAR scan lists. The first byte picks the reader.
#include <cstdint>
#include <string>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/position_readers.h"
#include "epiloc/io/result.h"
#include "fuzz_util.h"
#include "io_internal.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const int which = data[0] % 5;
  const std::string path = epiloc::fuzz::WriteInput("input.csv", data + 1, size - 1);
  try {
    switch (which) {
      case 0: {
        epiloc::CsvReader csv(path);
        while (csv.Next()) {
          for (const std::string& column : csv.header()) {
            try {
              (void)csv.GetDouble(column);
            } catch (const epiloc::Error&) {
            }
            (void)csv.GetOptionalDouble(column);
          }
        }
        break;
      }
      case 1: {
        const epiloc::ResultTable table = epiloc::ReadResultCsv(path);
        (void)table.Methods();
        break;
      }
      case 2:
        (void)epiloc::ReadPositionCsv(path, epiloc::Geodetic{49.0, 8.4, 110.0});
        break;
      case 3:
        (void)epiloc::ReadFramesCsv(path, epiloc::fuzz::ScratchDir().string(), size % 2 == 0);
        break;
      case 4:
        (void)epiloc::ReadLidarCsv(path, epiloc::fuzz::ScratchDir().string());
        break;
    }
  } catch (const epiloc::Error&) {
  }
  return 0;
}
