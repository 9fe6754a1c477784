// Content hashes (XXH3, 128 bit) of files and buffers, as 32 lower-case hex digits.
#pragma once

#include <cstddef>
#include <string>

namespace epiloc {

std::string HashBytes(const void* data, size_t size);
// Throws Error naming the file if it cannot be read.
std::string HashFile(const std::string& path);

}  // namespace epiloc
