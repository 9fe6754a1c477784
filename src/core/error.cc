#include "epiloc/core/error.h"

namespace epiloc {

std::string Where(const std::string& path, int64_t line) {
  if (line >= 1) return fmt::format("{}:{}", path, line);
  return path;
}

}  // namespace epiloc
