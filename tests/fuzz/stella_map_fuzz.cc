// stella_vslam's MessagePack map database (io/stella_map.h).
#include <cstdint>
#include <string>

#include "epiloc/core/error.h"
#include "epiloc/io/stella_map.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = epiloc::fuzz::WriteInput("map.msg", data, size);
  try {
    (void)epiloc::IsMessagePackFile(path);
    (void)epiloc::ReadStellaMap(path);
  } catch (const epiloc::Error&) {
  }
  return 0;
}
