#include "epiloc/retrieval/global_descriptor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using ::testing::HasSubstr;

// A toy world of descriptors: `num_patterns` prototype SIFT vectors; each place shows its own
// variants of some of them, and each image of a place a noisy subset of the place's variants.
class DescriptorWorld {
 public:
  DescriptorWorld(int num_places, int features_per_place, uint32_t seed) : rng_(seed) {
    std::uniform_int_distribution<int> byte(0, 120);
    for (int p = 0; p < kNumPatterns; ++p) {
      Eigen::VectorXf pattern(128);
      for (int i = 0; i < 128; ++i) pattern[i] = static_cast<float>(byte(rng_));
      patterns_.push_back(pattern);
    }
    std::uniform_int_distribution<int> pick(0, kNumPatterns - 1);
    for (int place = 0; place < num_places; ++place) {
      std::vector<Eigen::VectorXf> features;
      for (int f = 0; f < features_per_place; ++f) {
        features.push_back(Noisy(patterns_[pick(rng_)], 12.0f));
      }
      places_.push_back(features);
    }
  }

  // An image of `place`: each of its features seen with probability 0.8, with pixel noise, in
  // random order.
  FeatureDescriptors Image(int place) {
    std::vector<Eigen::VectorXf> seen;
    std::bernoulli_distribution visible(0.8);
    for (const Eigen::VectorXf& feature : places_[place]) {
      if (visible(rng_)) seen.push_back(Noisy(feature, 4.0f));
    }
    std::shuffle(seen.begin(), seen.end(), rng_);
    FeatureDescriptors image(static_cast<Eigen::Index>(seen.size()), 128);
    for (size_t r = 0; r < seen.size(); ++r) {
      for (int i = 0; i < 128; ++i) {
        image(r, i) = static_cast<uint8_t>(std::clamp(std::lround(seen[r][i]), 0L, 255L));
      }
    }
    return image;
  }

 private:
  static constexpr int kNumPatterns = 150;

  Eigen::VectorXf Noisy(const Eigen::VectorXf& v, float sigma) {
    std::normal_distribution<float> noise(0.0f, sigma);
    Eigen::VectorXf out = v;
    for (int i = 0; i < 128; ++i) out[i] = std::max(0.0f, out[i] + noise(rng_));
    return out;
  }

  std::mt19937 rng_;
  std::vector<Eigen::VectorXf> patterns_;
  std::vector<std::vector<Eigen::VectorXf>> places_;
};

std::vector<const FeatureDescriptors*> Pointers(const std::vector<FeatureDescriptors>& images) {
  std::vector<const FeatureDescriptors*> pointers;
  for (const auto& image : images) pointers.push_back(&image);
  return pointers;
}

VocabularyOptions SmallOptions() {
  VocabularyOptions options;
  options.num_words = 16;
  options.pca_dims = 32;
  options.features_per_image = 1000;
  return options;
}

// One image per place, `num_places` places.
std::vector<FeatureDescriptors> Images(DescriptorWorld* world, int num_places) {
  std::vector<FeatureDescriptors> images;
  for (int p = 0; p < num_places; ++p) images.push_back(world->Image(p));
  return images;
}

template <typename Function>
void ExpectError(Function function, const std::string& part) {
  try {
    function();
    ADD_FAILURE() << "no exception, expected one mentioning '" << part << "'";
  } catch (const Error& error) {
    EXPECT_THAT(error.what(), HasSubstr(part));
  }
}

TEST(VocabularyOptions, CheckNamesTheInvalidField) {
  const auto expect_invalid = [](auto change, const std::string& field) {
    VocabularyOptions options;
    change(options);
    ExpectError([&] { options.Check(); }, field);
  };
  expect_invalid([](VocabularyOptions& o) { o.num_words = 0; }, "num_words");
  expect_invalid([](VocabularyOptions& o) { o.pca_dims = 0; }, "pca_dims");
  expect_invalid([](VocabularyOptions& o) { o.max_training_descriptors = 10; },
                 "max_training_descriptors");
  expect_invalid([](VocabularyOptions& o) { o.features_per_image = 0; }, "features_per_image");
  expect_invalid([](VocabularyOptions& o) { o.max_training_images = 1; }, "max_training_images");
  expect_invalid([](VocabularyOptions& o) { o.whitening_regularization = -1; }, "whitening");
  VocabularyOptions().Check();
}

TEST(GlobalDescriptorModel, TrainingIsDeterministicPerSeed) {
  DescriptorWorld world(30, 200, 1);
  const auto images = Images(&world, 30);
  VocabularyOptions options = SmallOptions();
  const auto a = GlobalDescriptorModel::Train(Pointers(images), options).Serialize();
  const auto b = GlobalDescriptorModel::Train(Pointers(images), options).Serialize();
  EXPECT_TRUE(a == b);
  options.seed = 2;
  const auto c = GlobalDescriptorModel::Train(Pointers(images), options).Serialize();
  EXPECT_EQ(a.size(), c.size());
  EXPECT_FALSE(a == c);
}

TEST(GlobalDescriptorModel, VladIsPowerAndIntraNormalised) {
  DescriptorWorld world(20, 200, 2);
  const auto images = Images(&world, 20);
  const auto model = GlobalDescriptorModel::Train(Pointers(images), SmallOptions());
  ASSERT_EQ(model.vlad_dims(), 16 * 128);
  // A few descriptors touch only some words: the others' blocks stay zero, every other block has
  // the same norm.
  const FeatureDescriptors few = images[3].topRows(5);
  const Eigen::VectorXf vlad = model.Vlad(few);
  EXPECT_NEAR(vlad.norm(), 1.0f, 1e-5f);
  std::vector<float> norms;
  for (int w = 0; w < model.num_words(); ++w) norms.push_back(vlad.segment<128>(128 * w).norm());
  const int nonzero =
      static_cast<int>(std::count_if(norms.begin(), norms.end(), [](float n) { return n > 0.0f; }));
  ASSERT_GE(nonzero, 1);
  ASSERT_LE(nonzero, 5);
  for (const float norm : norms) {
    if (norm > 0.0f) {
      EXPECT_NEAR(norm, 1.0f / std::sqrt(static_cast<float>(nonzero)), 1e-5f);
    }
  }
  EXPECT_TRUE(model.Vlad(FeatureDescriptors(0, 128)).isZero());
}

TEST(GlobalDescriptorModel, ComputeIsAUnitVectorIndependentOfFeatureOrder) {
  DescriptorWorld world(20, 200, 3);
  const auto images = Images(&world, 20);
  const auto model = GlobalDescriptorModel::Train(Pointers(images), SmallOptions());
  EXPECT_EQ(model.dims(), 19);  // 20 training images: rank 19 after centring
  const Eigen::VectorXf d = model.Compute(images[5]);
  ASSERT_EQ(d.size(), model.dims());
  EXPECT_NEAR(d.norm(), 1.0f, 1e-5f);
  FeatureDescriptors reversed = images[5].colwise().reverse();
  EXPECT_TRUE(model.Compute(reversed).isApprox(d, 1e-4f));
  // Only the strongest features_per_image rows count.
  VocabularyOptions options = SmallOptions();
  options.features_per_image = 50;
  const auto prefix_model = GlobalDescriptorModel::Train(Pointers(images), options);
  FeatureDescriptors changed_tail = images[5];
  changed_tail.bottomRows(changed_tail.rows() - 50).setZero();
  EXPECT_EQ(prefix_model.Compute(changed_tail), prefix_model.Compute(images[5]));
  // No features: the zero vector.
  EXPECT_TRUE(model.Compute(FeatureDescriptors(0, 128)).isZero());
}

TEST(GlobalDescriptorModel, WhiteningDecorrelatesTheTrainingImages) {
  DescriptorWorld world(40, 200, 4);
  const auto images = Images(&world, 40);
  for (const double regularization : {0.0, 0.1}) {
    SCOPED_TRACE(regularization);
    VocabularyOptions options = SmallOptions();
    options.whitening_regularization = regularization;
    const auto model = GlobalDescriptorModel::Train(Pointers(images), options);
    ASSERT_EQ(model.dims(), 32);
    const Eigen::VectorXf& lambda = model.eigenvalues();
    for (int i = 1; i < model.dims(); ++i) EXPECT_LE(lambda[i], lambda[i - 1]);
    EXPECT_NEAR(model.whitening_epsilon(), regularization * lambda.mean(), 1e-6 * lambda.mean());
    Eigen::MatrixXd whitened(model.dims(), images.size());
    for (size_t i = 0; i < images.size(); ++i) {
      whitened.col(i) = model.Whiten(model.Vlad(images[i])).cast<double>();
    }
    // Mean zero, covariance diag(lambda / (lambda + epsilon)).
    EXPECT_LT(whitened.rowwise().mean().norm(), 1e-4);
    const Eigen::MatrixXd covariance =
        whitened * whitened.transpose() / static_cast<double>(images.size() - 1);
    Eigen::MatrixXd expected = Eigen::MatrixXd::Zero(model.dims(), model.dims());
    for (int i = 0; i < model.dims(); ++i) {
      expected(i, i) = lambda[i] / (lambda[i] + model.whitening_epsilon());
    }
    EXPECT_LT((covariance - expected).cwiseAbs().maxCoeff(), 2e-3);
  }
}

TEST(GlobalDescriptorModel, RetrievesOtherImagesOfTheSamePlace) {
  DescriptorWorld world(60, 300, 5);
  const auto database = Images(&world, 60);
  const auto model = GlobalDescriptorModel::Train(Pointers(database), SmallOptions());
  GlobalIndex index;
  for (size_t i = 0; i < database.size(); ++i) {
    index.Add(static_cast<int64_t>(i), model.Compute(database[i]));
  }
  int correct = 0;
  for (int place = 0; place < 60; ++place) {
    const auto results = index.Search(model.Compute(world.Image(place)), 1);
    ASSERT_EQ(results.size(), 1u);
    correct += results[0].first == place;
  }
  std::cout << "toy world: recall@1 " << correct << "/60\n";
  EXPECT_GE(correct, 58);
}

TEST(GlobalDescriptorModel, TrainingRefusesTooLittleData) {
  DescriptorWorld world(3, 100, 6);
  const auto images = Images(&world, 3);
  ExpectError([&] { GlobalDescriptorModel::Train({&images[0]}, SmallOptions()); },
              "at least 2 images");
  VocabularyOptions options = SmallOptions();
  options.num_words = 500;
  options.max_training_descriptors = 1000;
  ExpectError([&] { GlobalDescriptorModel::Train(Pointers(images), options); },
              "for a vocabulary of 500 words");
  ExpectError(
      [&] {
        GlobalDescriptorModel::Train({&images[0], &images[0]}, SmallOptions());
      },
      "identical");
  ExpectError([&] { GlobalDescriptorModel().Compute(images[0]); }, "empty");
}

TEST(GlobalDescriptorModel, SerializationRoundTrips) {
  DescriptorWorld world(12, 200, 7);
  const auto images = Images(&world, 12);
  const auto model = GlobalDescriptorModel::Train(Pointers(images), SmallOptions());
  const std::vector<uint8_t> bytes = model.Serialize();
  EXPECT_EQ(bytes.size(), 24u + 4u * (16 * 128 + 16 * 128 + 11 + 11 * 16 * 128));
  const auto loaded = GlobalDescriptorModel::Deserialize(bytes);
  EXPECT_EQ(loaded.Serialize(), bytes);
  EXPECT_EQ(loaded.dims(), model.dims());
  EXPECT_EQ(loaded.num_words(), model.num_words());
  EXPECT_EQ(loaded.features_per_image(), model.features_per_image());
  for (const auto& image : images) EXPECT_EQ(loaded.Compute(image), model.Compute(image));
}

TEST(GlobalDescriptorModel, CorruptBlobsAreRefused) {
  DescriptorWorld world(5, 100, 8);
  const auto images = Images(&world, 5);
  const std::vector<uint8_t> good =
      GlobalDescriptorModel::Train(Pointers(images), SmallOptions()).Serialize();
  const auto expect_corrupt = [](std::vector<uint8_t> bytes, const std::string& part) {
    ExpectError([&] { GlobalDescriptorModel::Deserialize(bytes); }, part);
  };
  expect_corrupt({}, "not a model blob");
  expect_corrupt({good.begin(), good.begin() + 20}, "not a model blob");
  std::vector<uint8_t> bytes = good;
  bytes[0] = 'X';
  expect_corrupt(bytes, "not a model blob");
  bytes = good;
  bytes[4] = 2;
  expect_corrupt(bytes, "version 2 is not supported");
  bytes = good;
  bytes[8] = 0;  // zero words
  expect_corrupt(bytes, "corrupt header");
  bytes = good;
  bytes[12] = 5;  // dims 5 instead of 4
  expect_corrupt(bytes, "bytes, expected");
  bytes = good;
  bytes.pop_back();
  expect_corrupt(bytes, "bytes, expected");
  bytes = good;
  bytes.push_back(0);
  expect_corrupt(bytes, "bytes, expected");
  bytes = good;
  // A NaN (0x7fc00000 little-endian) in the middle of the components.
  const size_t at = bytes.size() - 4 * 100;
  bytes[at] = 0x00, bytes[at + 1] = 0x00, bytes[at + 2] = 0xc0, bytes[at + 3] = 0x7f;
  expect_corrupt(bytes, "non-finite value in its components");
  ExpectError([&] { GlobalDescriptorModel().Serialize(); }, "empty");
}

TEST(GlobalIndex, SearchRanksByDotProduct) {
  GlobalIndex index;
  EXPECT_TRUE(index.Search(Eigen::Vector3f(1, 0, 0), 3).empty());
  index.Add(10, Eigen::Vector3f(1, 0, 0));
  index.Add(11, Eigen::Vector3f(0, 1, 0));
  index.Add(12, Eigen::Vector3f(0.6f, 0.8f, 0));
  index.Add(13, Eigen::Vector3f(0, 0, -1));
  index.Add(14, Eigen::Vector3f(0, 1, 0));  // same as 11: ties keep insertion order
  EXPECT_EQ(index.size(), 5);
  EXPECT_EQ(index.dims(), 3);
  const auto results = index.Search(Eigen::Vector3f(0, 1, 0), 3);
  ASSERT_EQ(results.size(), 3u);
  EXPECT_EQ(results[0], std::make_pair(int64_t{11}, 1.0f));
  EXPECT_EQ(results[1], std::make_pair(int64_t{14}, 1.0f));
  EXPECT_EQ(results[2].first, 12);
  EXPECT_FLOAT_EQ(results[2].second, 0.8f);
  const auto all = index.Search(Eigen::Vector3f(0, 0, 1), 100);
  ASSERT_EQ(all.size(), 5u);
  EXPECT_EQ(all.back(), std::make_pair(int64_t{13}, -1.0f));
  ExpectError([&] { index.Search(Eigen::Vector3f(0, 0, 1), 0); }, "k must be >= 1");
  ExpectError([&] { index.Search(Eigen::Vector2f(0, 1), 1); }, "query has 2 values");
  ExpectError([&] { index.Add(15, Eigen::Vector4f(0, 1, 0, 0)); }, "has 4 values");
  ExpectError([&] { index.Add(15, Eigen::Vector3f(0, NAN, 0)); }, "non-finite");
}

// Cost of the two per-query steps, printed (no assertion: a benchmark, not a test).
TEST(GlobalDescriptorModel, PrintsTheCostPerQuery) {
  // 300 training images, so the descriptor has the full 256 dimensions.
  DescriptorWorld world(300, 300, 9);
  const auto images = Images(&world, 300);
  FeatureDescriptors query(0, 128);
  for (int place = 0; query.rows() < 4000; ++place) {
    const FeatureDescriptors more = world.Image(place);
    FeatureDescriptors joined(query.rows() + more.rows(), 128);
    joined << query, more;
    query = joined;
  }
  query.conservativeResize(4000, 128);
  for (const int features : {1000, 4000}) {
    VocabularyOptions options;  // 64 words, 256 dimensions
    options.features_per_image = features;
    options.max_training_descriptors = 20000;
    const auto model = GlobalDescriptorModel::Train(Pointers(images), options);
    ASSERT_EQ(model.dims(), 256);
    const int repeats = 20;
    const auto start = std::chrono::steady_clock::now();
    float sink = 0;
    for (int r = 0; r < repeats; ++r) sink += model.Compute(query)[0];
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count() /
        repeats;
    std::cout << "Compute(): " << ms << " ms per frame of 4000 features (" << features
              << " used, 64 words, " << model.dims() << " dims)\n";
    EXPECT_TRUE(std::isfinite(sink));
  }
  std::mt19937 rng(10);
  std::normal_distribution<float> normal;
  GlobalIndex index;
  index.Reserve(10000);
  Eigen::VectorXf v(256);
  for (int i = 0; i < 10000; ++i) {
    for (int d = 0; d < 256; ++d) v[d] = normal(rng);
    index.Add(i, v.normalized());
  }
  const int repeats = 50;
  const auto start = std::chrono::steady_clock::now();
  int64_t sink = 0;
  for (int r = 0; r < repeats; ++r) sink += index.Search(v.normalized(), 10)[0].first;
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() /
      repeats;
  EXPECT_EQ(sink, 9999 * repeats);
  std::cout << "Search(): " << ms << " ms for top-10 of 10,000 x 256\n";
}

}  // namespace
}  // namespace epiloc
