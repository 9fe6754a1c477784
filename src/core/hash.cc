#include "epiloc/core/hash.h"

#include <fstream>
#include <memory>
#include <vector>

#include <fmt/format.h>
#include <xxhash.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

std::string ToHex(const XXH128_hash_t& hash) {
  return fmt::format("{:016x}{:016x}", hash.high64, hash.low64);
}

}  // namespace

std::string HashBytes(const void* data, size_t size) { return ToHex(XXH3_128bits(data, size)); }

std::string HashFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Throw("{}: cannot open file", path);
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(),
                                                                  &XXH3_freeState);
  XXH3_128bits_reset(state.get());
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    XXH3_128bits_update(state.get(), buffer.data(), static_cast<size_t>(in.gcount()));
  }
  if (in.bad()) Throw("{}: read error", path);
  return ToHex(XXH3_128bits_digest(state.get()));
}

}  // namespace epiloc
