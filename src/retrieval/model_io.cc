// The retrieval model's byte layout (db_schema/README.md, "Retrieval model blob").

#include <cmath>
#include <cstring>

#include "epiloc/core/error.h"
#include "epiloc/retrieval/global_descriptor.h"

namespace epiloc {
namespace {

constexpr char kMagic[4] = {'E', 'G', 'D', 'M'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 24;  // magic, version, num_words, dims, features, epsilon
constexpr uint32_t kMaxWords = 4096;

class Writer {
 public:
  void U32(uint32_t value) {
    for (int b = 0; b < 4; ++b) bytes_.push_back(static_cast<uint8_t>(value >> (8 * b)));
  }
  void F32(float value) {
    uint32_t bits;
    std::memcpy(&bits, &value, sizeof(bits));
    U32(bits);
  }
  void Floats(const float* values, Eigen::Index count) {
    for (Eigen::Index i = 0; i < count; ++i) F32(values[i]);
  }
  std::vector<uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

// Reads within a buffer whose total size was checked up front.
class Reader {
 public:
  explicit Reader(const std::vector<uint8_t>& bytes) : bytes_(bytes) {}
  uint32_t U32() {
    uint32_t value = 0;
    for (int b = 0; b < 4; ++b) value |= static_cast<uint32_t>(bytes_[position_ + b]) << (8 * b);
    position_ += 4;
    return value;
  }
  float F32() {
    const uint32_t bits = U32();
    float value;
    std::memcpy(&value, &bits, sizeof(value));
    return value;
  }
  // Reads `count` floats, throwing for a non-finite one (a corrupt blob).
  void Floats(float* values, Eigen::Index count, const char* what) {
    for (Eigen::Index i = 0; i < count; ++i) {
      values[i] = F32();
      EPILOC_CHECK(std::isfinite(values[i]), "retrieval model: non-finite value in its {}", what);
    }
  }

 private:
  const std::vector<uint8_t>& bytes_;
  size_t position_ = 0;
};

}  // namespace

std::vector<uint8_t> GlobalDescriptorModel::Serialize() const {
  EPILOC_CHECK(!empty(), "retrieval: cannot serialize an empty global descriptor model");
  Writer writer;
  writer.bytes().reserve(kHeaderBytes + 4 * (centres_.size() + mean_.size() + eigenvalues_.size() +
                                             components_.size()));
  for (const char c : kMagic) writer.bytes().push_back(static_cast<uint8_t>(c));
  writer.U32(kVersion);
  writer.U32(static_cast<uint32_t>(num_words()));
  writer.U32(static_cast<uint32_t>(dims_));
  writer.U32(static_cast<uint32_t>(features_per_image_));
  writer.F32(whitening_epsilon_);
  writer.Floats(centres_.data(), centres_.size());
  writer.Floats(mean_.data(), mean_.size());
  writer.Floats(eigenvalues_.data(), eigenvalues_.size());
  writer.Floats(components_.data(), components_.size());
  return std::move(writer.bytes());
}

GlobalDescriptorModel GlobalDescriptorModel::Deserialize(const std::vector<uint8_t>& bytes) {
  EPILOC_CHECK(bytes.size() >= kHeaderBytes && std::memcmp(bytes.data(), kMagic, 4) == 0,
               "retrieval model: not a model blob (no 'EGDM' header in {} bytes)", bytes.size());
  Reader reader(bytes);
  reader.U32();  // magic
  const uint32_t version = reader.U32();
  EPILOC_CHECK(version == kVersion,
               "retrieval model: version {} is not supported by this epiloc (reads {})", version,
               kVersion);
  const uint32_t num_words = reader.U32();
  const uint32_t dims = reader.U32();
  const uint32_t features_per_image = reader.U32();
  const float epsilon = reader.F32();
  EPILOC_CHECK(num_words >= 1 && num_words <= kMaxWords,
               "retrieval model: corrupt header ({} words)", num_words);
  const uint64_t vlad_dims = 128ull * num_words;
  EPILOC_CHECK(dims >= 1 && dims <= vlad_dims, "retrieval model: corrupt header ({} dimensions)",
               dims);
  EPILOC_CHECK(features_per_image >= 1 && features_per_image <= (1u << 30),
               "retrieval model: corrupt header ({} features per image)", features_per_image);
  EPILOC_CHECK(std::isfinite(epsilon) && epsilon >= 0.0f,
               "retrieval model: corrupt header (whitening epsilon {})", epsilon);
  // At most 4096 * 128 * (4096 * 128 + 2) floats: no overflow in 64 bits.
  const uint64_t expected =
      kHeaderBytes + 4 * (vlad_dims + vlad_dims + dims + uint64_t{dims} * vlad_dims);
  EPILOC_CHECK(bytes.size() == expected,
               "retrieval model: {} bytes, expected {} for {} words and {} dimensions",
               bytes.size(), expected, num_words, dims);

  GlobalDescriptorModel model;
  model.features_per_image_ = static_cast<int>(features_per_image);
  model.dims_ = static_cast<int>(dims);
  model.whitening_epsilon_ = epsilon;
  model.centres_.resize(num_words, 128);
  model.mean_.resize(static_cast<Eigen::Index>(vlad_dims));
  model.eigenvalues_.resize(dims);
  model.components_.resize(dims, static_cast<Eigen::Index>(vlad_dims));
  reader.Floats(model.centres_.data(), model.centres_.size(), "centres");
  reader.Floats(model.mean_.data(), model.mean_.size(), "mean");
  reader.Floats(model.eigenvalues_.data(), model.eigenvalues_.size(), "eigenvalues");
  reader.Floats(model.components_.data(), model.components_.size(), "components");
  EPILOC_CHECK((model.eigenvalues_.array() + epsilon > 0.0f).all(),
               "retrieval model: corrupt eigenvalues (not positive)");
  model.UpdateScale();
  return model;
}

}  // namespace epiloc
