// The one exception type of epiloc and the checks that throw it.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace epiloc {

// Thrown by library code for bad input, I/O and database failures and violated preconditions.
// The message is one line and names the file (and line) it concerns where there is one; only the
// CLI's main catches it.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// "path:line" (line >= 1) or "path" (line < 1): the prefix of a message about a place in a file.
std::string Where(const std::string& path, int64_t line = 0);

// `text` (bytes from an input file) made safe to quote in a one-line message: control bytes
// (newline, escape sequences that would drive the terminal, ...) become \xNN, a backslash stays
// one; at most `max_bytes` bytes are kept ("..." marks a cut).
std::string Printable(const std::string& text, size_t max_bytes = 200);

// Throws Error with a formatted message.
template <typename... Args>
[[noreturn]] void Throw(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace epiloc

// Throws epiloc::Error("<message>") unless `condition` holds. The message is a fmt format string.
#define EPILOC_CHECK(condition, ...) \
  do {                               \
    if (!(condition)) {              \
      ::epiloc::Throw(__VA_ARGS__);  \
    }                                \
  } while (false)
