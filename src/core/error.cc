#include "epiloc/core/error.h"

#include <algorithm>

namespace epiloc {

std::string Where(const std::string& path, int64_t line) {
  if (line >= 1) return fmt::format("{}:{}", path, line);
  return path;
}

std::string Printable(const std::string& text, size_t max_bytes) {
  std::string out;
  const size_t n = std::min(text.size(), max_bytes);
  out.reserve(n + 8);
  for (size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f) {
      out += fmt::format("\\x{:02x}", c);
    } else {
      out += static_cast<char>(c);
    }
  }
  if (text.size() > max_bytes) out += "...";
  return out;
}

}  // namespace epiloc
