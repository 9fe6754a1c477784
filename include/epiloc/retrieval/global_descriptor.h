// Whole-image retrieval: one global descriptor per image, so a query frame can be placed on the
// route without a position prior (start of a drive, recovery of a lost track).
//
// Method: VLAD (Jegou et al., "Aggregating local descriptors into a compact image
// representation", CVPR 2010) of RootSIFT descriptors (Arandjelovic & Zisserman, "Three things
// everyone should know to improve object retrieval", CVPR 2012) with signed-square-root power
// normalisation and intra-normalisation (Arandjelovic & Zisserman, "All about VLAD", CVPR 2013),
// reduced by PCA with regularised whitening (Jegou & Chum, "Negative evidence and co-occurrences
// in image retrieval: the benefit of PCA and whitening", ECCV 2012). Two descriptors are compared
// by their dot product (cosine similarity, both are unit vectors).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "epiloc/feature/types.h"

namespace epiloc {

struct VocabularyOptions {
  // Visual words: k-means centres of RootSIFT descriptors; the VLAD vector has num_words * 128
  // dimensions.
  int num_words = 64;
  // Dimensions of the global descriptor after PCA (fewer when trained on fewer images, below).
  int pca_dims = 256;
  // K-means runs on at most this many descriptors, an even subsample across the training images.
  int max_training_descriptors = 200000;
  // Strongest features of an image (its first rows, FeatureSet order) used for VLAD and training.
  int features_per_image = 1000;
  // Train() uses at most this many images, evenly spaced over those given, for k-means and PCA
  // (bounds memory and the O(n^2) PCA; BuildRetrievalIndex reads only these from the database).
  int max_training_images = 1000;
  // Whitening regularisation: each PCA component is scaled by 1 / sqrt(eigenvalue + epsilon) with
  // epsilon = whitening_regularization * (mean of the kept eigenvalues); 0 = full whitening,
  // large = plain PCA. 1 whitens the strong components and leaves the weak ones, which hold
  // noise when the model is trained on few images, nearly as they are.
  double whitening_regularization = 1.0;
  // Seed of the k-means++ initialisation; the same images and options give the same model on
  // every platform.
  uint64_t seed = 1;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// The trained model ("vocabulary"): k-means centres of RootSIFT descriptors and a PCA whitening
// of the normalised VLAD vectors of the training images. Immutable once trained; Compute() is
// thread-safe.
class GlobalDescriptorModel {
 public:
  // An empty model (Compute() throws); obtain one from Train() or Deserialize().
  GlobalDescriptorModel() = default;

  // Trains on the descriptors of `images` (pointers are only read during the call; null entries
  // are not allowed): k-means (k-means++ seeded from options.seed, at most 50 Lloyd iterations)
  // on an even subsample of the images' strongest descriptors, then PCA of their VLAD vectors.
  // The descriptor has min(pca_dims, n - 1) dimensions for n training images (n - 1 is the rank
  // of n centred vectors), fewer still if some images are identical. Throws Error for fewer than
  // two images, fewer descriptors than num_words, or training images whose VLAD vectors are all
  // alike.
  static GlobalDescriptorModel Train(const std::vector<const FeatureDescriptors*>& images,
                                     const VocabularyOptions& options);

  bool empty() const { return dims_ == 0; }
  int num_words() const { return static_cast<int>(centres_.rows()); }
  int vlad_dims() const { return 128 * num_words(); }
  int dims() const { return dims_; }  // of Compute()'s result
  int features_per_image() const { return features_per_image_; }
  // PCA eigenvalues (variances of the normalised VLAD vectors along the components), decreasing.
  const Eigen::VectorXf& eigenvalues() const { return eigenvalues_; }
  float whitening_epsilon() const { return whitening_epsilon_; }

  // The global descriptor: a unit vector of dims() values (VLAD, then Whiten, then L2). An image
  // without features gives the zero vector (similarity 0 to every image).
  Eigen::VectorXf Compute(const FeatureDescriptors& descriptors) const;

  // The steps of Compute(), for tests and diagnostics.
  // VLAD of the first features_per_image() rows: residuals to the nearest word summed per word,
  // signed square root, each word's block L2-normalised, then the whole vector (vlad_dims()
  // values; zero without features).
  Eigen::VectorXf Vlad(const FeatureDescriptors& descriptors) const;
  // PCA projection and whitening of a VLAD vector, not normalised: component i of
  // (vlad - mean) scaled by 1 / sqrt(eigenvalue_i + whitening_epsilon()).
  Eigen::VectorXf Whiten(const Eigen::VectorXf& vlad) const;

  // The model as bytes (layout in db_schema/README.md, "Retrieval blobs"): little-endian,
  // magic and version first, so a model moves between hosts.
  std::vector<uint8_t> Serialize() const;
  // Throws Error for bytes that are not a model of this version, are truncated or too long, or
  // hold non-finite values.
  static GlobalDescriptorModel Deserialize(const std::vector<uint8_t>& bytes);

 private:
  void UpdateScale();

  int features_per_image_ = 0;
  int dims_ = 0;
  float whitening_epsilon_ = 0.0f;
  Eigen::Matrix<float, Eigen::Dynamic, 128, Eigen::RowMajor> centres_;  // num_words x 128
  Eigen::VectorXf mean_;                                                // vlad_dims
  Eigen::VectorXf eigenvalues_;                                         // dims
  // dims x vlad_dims, orthonormal rows (the principal axes, strongest first).
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> components_;
  Eigen::VectorXf scale_;  // dims: 1 / sqrt(eigenvalue + epsilon)
};

// Exhaustive search of global descriptors by dot product (10,000 x 256 floats: about a
// millisecond). Copies the vectors it is given.
class GlobalIndex {
 public:
  // Adds one descriptor; the first one fixes dims(). Throws Error for a descriptor of another
  // size, an empty or non-finite one. Ids need not be unique or ordered.
  void Add(int64_t id, const Eigen::VectorXf& descriptor);
  void Reserve(int64_t num_entries);

  int64_t size() const { return static_cast<int64_t>(ids_.size()); }
  int dims() const { return dims_; }
  bool empty() const { return ids_.empty(); }

  // The min(k, size()) entries most similar to `query`: (id, dot product), highest first (ties
  // by insertion order). Throws Error for k < 1 or a query of another size than dims().
  std::vector<std::pair<int64_t, float>> Search(const Eigen::VectorXf& query, int k) const;

 private:
  int dims_ = 0;
  std::vector<int64_t> ids_;
  std::vector<float> data_;  // entry j at [j * dims_, (j + 1) * dims_)
};

}  // namespace epiloc
