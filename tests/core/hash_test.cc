#include "epiloc/core/hash.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

std::string Hash(const std::string& text) {
  return HashBytes(text.data(), text.size());
}

// Golden values: XXH3-128 in its canonical (big-endian) hex form, from
// libxxhash 0.8's XXH128_canonicalFromHash; the empty-input value is the
// published XXH3-128 test vector. A change here would invalidate the image
// hashes stored in every database.
TEST(HashBytes, KnownValuesAreStable) {
  EXPECT_EQ(Hash(""), "99aa06d3014798d86001c324468d497f");
  EXPECT_EQ(HashBytes(nullptr, 0), "99aa06d3014798d86001c324468d497f");
  EXPECT_EQ(Hash("hello"), "b5e9c1ad071b3e7fc779cfaa5e523818");
  EXPECT_EQ(Hash("The quick brown fox jumps over the lazy dog"),
            "ddd650205ca3e7fa24a1cc2e3a8a7651");
}

TEST(HashBytes, DiffersForDifferentInput) {
  EXPECT_NE(Hash("hello"), Hash("hellp"));
  EXPECT_NE(Hash("hello"), Hash("hello "));
  EXPECT_NE(Hash("a"), Hash(std::string("a\0", 2)));
  std::mt19937 rng(1);
  std::string data(1000, '\0');
  for (char& c : data) c = static_cast<char>(rng() & 0xff);
  const std::string hash = Hash(data);
  EXPECT_EQ(hash.size(), 32u);
  EXPECT_EQ(hash.find_first_not_of("0123456789abcdef"), std::string::npos);
  data[500] ^= 1;
  EXPECT_NE(Hash(data), hash);
}

TEST(HashFile, EqualsHashOfTheContentAcrossBufferBoundaries) {
  const fs::path path =
      fs::temp_directory_path() /
      ("epiloc_hash_test_" + std::to_string(getpid()) + ".bin");
  std::mt19937 rng(2);
  // Larger than the 1 MiB read buffer and not a multiple of it.
  for (const size_t size :
       {size_t{0}, size_t{5}, size_t{(1 << 20) - 1}, size_t{(3 << 20) + 17}}) {
    SCOPED_TRACE(size);
    std::string data(size, '\0');
    for (char& c : data) c = static_cast<char>(rng() & 0xff);
    std::ofstream(path, std::ios::binary) << data;
    EXPECT_EQ(HashFile(path.string()), Hash(data));
  }
  fs::remove(path);
}

TEST(HashFile, MissingFileIsNamed) {
  const std::string path = "/nonexistent/epiloc/image.png";
  try {
    HashFile(path);
    ADD_FAILURE() << "no exception";
  } catch (const Error& error) {
    EXPECT_THAT(error.what(), ::testing::HasSubstr(path + ": cannot open"));
  }
}

}  // namespace
}  // namespace epiloc
