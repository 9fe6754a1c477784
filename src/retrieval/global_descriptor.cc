#include "epiloc/retrieval/global_descriptor.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "epiloc/core/error.h"
#include "epiloc/feature/matcher.h"
#include "kmeans.h"

namespace epiloc {
namespace {

using internal::DescriptorMatrixF;
using RowMatrixF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

constexpr int kMaxKMeansIterations = 50;
// PCA components whose variance is below this fraction of the largest are dropped: they hold
// rounding noise only (duplicate training images).
constexpr double kMinRelativeEigenvalue = 1e-9;

// `count` indices spread evenly over [0, n).
std::vector<size_t> EvenSubset(size_t n, size_t count) {
  std::vector<size_t> indices;
  if (count >= n) {
    for (size_t i = 0; i < n; ++i) indices.push_back(i);
    return indices;
  }
  for (size_t j = 0; j < count; ++j) indices.push_back(j * n / count);
  return indices;
}

int NumUsedRows(const FeatureDescriptors& descriptors, int features_per_image) {
  return static_cast<int>(std::min<Eigen::Index>(descriptors.rows(), features_per_image));
}

}  // namespace

void VocabularyOptions::Check() const {
  EPILOC_CHECK(num_words >= 1 && num_words <= 4096,
               "retrieval: num_words must be in [1, 4096], got {}", num_words);
  EPILOC_CHECK(pca_dims >= 1, "retrieval: pca_dims must be >= 1, got {}", pca_dims);
  EPILOC_CHECK(max_training_descriptors >= num_words,
               "retrieval: max_training_descriptors must be >= num_words ({}), got {}", num_words,
               max_training_descriptors);
  EPILOC_CHECK(features_per_image >= 1, "retrieval: features_per_image must be >= 1, got {}",
               features_per_image);
  EPILOC_CHECK(max_training_images >= 2, "retrieval: max_training_images must be >= 2, got {}",
               max_training_images);
  EPILOC_CHECK(std::isfinite(whitening_regularization) && whitening_regularization >= 0,
               "retrieval: whitening_regularization must be >= 0, got {}",
               whitening_regularization);
}

GlobalDescriptorModel GlobalDescriptorModel::Train(
    const std::vector<const FeatureDescriptors*>& images, const VocabularyOptions& options) {
  options.Check();
  EPILOC_CHECK(images.size() >= 2, "retrieval: training needs at least 2 images, got {}",
               images.size());
  for (const FeatureDescriptors* image : images) {
    EPILOC_CHECK(image != nullptr, "retrieval: null image in the training set");
  }
  std::vector<const FeatureDescriptors*> training;
  for (const size_t i : EvenSubset(images.size(), options.max_training_images)) {
    training.push_back(images[i]);
  }

  // The k-means sample: every step-th of the concatenated strongest descriptors.
  int64_t total = 0;
  for (const FeatureDescriptors* image : training) {
    total += NumUsedRows(*image, options.features_per_image);
  }
  EPILOC_CHECK(total >= options.num_words,
               "retrieval: {} training descriptors for a vocabulary of {} words", total,
               options.num_words);
  const int64_t sample_size = std::min<int64_t>(total, options.max_training_descriptors);
  DescriptorMatrixF sample(sample_size, 128);
  int64_t next = 0;    // next sample row to fill
  int64_t offset = 0;  // index of the image's first row in the concatenation
  for (const FeatureDescriptors* image : training) {
    const int rows = NumUsedRows(*image, options.features_per_image);
    const std::vector<float> root = ToRootSift(*image, rows);
    // Sample row j takes concatenated row floor(j * total / sample_size).
    while (next < sample_size) {
      const int64_t row = next * total / sample_size - offset;
      if (row >= rows) break;
      sample.row(next++) = Eigen::Map<const Eigen::Matrix<float, 1, 128>>(&root[row * 128]);
    }
    offset += rows;
  }

  GlobalDescriptorModel model;
  model.features_per_image_ = options.features_per_image;
  model.centres_ = internal::KMeans(sample, options.num_words, options.seed, kMaxKMeansIterations);
  sample.resize(0, 128);

  // PCA through the n x n Gram matrix of the centred VLAD vectors (n << vlad_dims).
  const Eigen::Index n = static_cast<Eigen::Index>(training.size());
  RowMatrixF vlads(n, model.vlad_dims());
  for (Eigen::Index i = 0; i < n; ++i) vlads.row(i) = model.Vlad(*training[i]).transpose();
  model.mean_ = vlads.colwise().mean().transpose();
  vlads.rowwise() -= model.mean_.transpose();
  const Eigen::MatrixXd gram = (vlads * vlads.transpose()).cast<double>();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(gram);
  EPILOC_CHECK(solver.info() == Eigen::Success, "retrieval: PCA eigen-decomposition failed");
  const Eigen::VectorXd& mu = solver.eigenvalues();  // increasing
  const double mu_max = mu[n - 1];
  EPILOC_CHECK(mu_max > 0.0, "retrieval: the {} training images have identical VLAD vectors", n);
  const Eigen::Index max_dims =
      std::min<Eigen::Index>({options.pca_dims, n - 1, model.vlad_dims()});
  Eigen::Index dims = 0;
  while (dims < max_dims && mu[n - 1 - dims] > kMinRelativeEigenvalue * mu_max) ++dims;

  // Principal axis j = X^T v_j / sqrt(mu_j) for the Gram eigenvector v_j; its variance is
  // mu_j / (n - 1).
  Eigen::MatrixXf top(n, dims);
  for (Eigen::Index j = 0; j < dims; ++j) {
    top.col(j) = solver.eigenvectors().col(n - 1 - j).cast<float>();
  }
  model.components_ = (vlads.transpose() * top).transpose();
  model.eigenvalues_.resize(dims);
  for (Eigen::Index j = 0; j < dims; ++j) {
    model.components_.row(j).normalize();  // exact unit length despite rounding
    model.eigenvalues_[j] = static_cast<float>(mu[n - 1 - j] / static_cast<double>(n - 1));
  }
  model.whitening_epsilon_ =
      static_cast<float>(options.whitening_regularization * model.eigenvalues_.mean());
  model.dims_ = static_cast<int>(dims);
  model.UpdateScale();
  return model;
}

void GlobalDescriptorModel::UpdateScale() {
  scale_ = (eigenvalues_.array() + whitening_epsilon_).rsqrt().matrix();
}

Eigen::VectorXf GlobalDescriptorModel::Vlad(const FeatureDescriptors& descriptors) const {
  EPILOC_CHECK(centres_.rows() > 0, "retrieval: the global descriptor model is empty");
  Eigen::VectorXf vlad = Eigen::VectorXf::Zero(vlad_dims());
  const int rows = NumUsedRows(descriptors, features_per_image_);
  if (rows == 0) return vlad;
  const std::vector<float> root = ToRootSift(descriptors, rows);
  const Eigen::Map<const DescriptorMatrixF> x(root.data(), rows, 128);
  std::vector<int> labels;
  internal::AssignNearest(x, centres_, /*parallel=*/false, &labels);
  for (int i = 0; i < rows; ++i) {
    vlad.segment<128>(128 * labels[i]) += (x.row(i) - centres_.row(labels[i])).transpose();
  }
  // Signed square root, then intra-normalisation: no single burst of similar features (a
  // repeated texture) dominates the vector.
  vlad = vlad.array().sign() * vlad.array().abs().sqrt();
  for (int w = 0; w < num_words(); ++w) {
    const float norm = vlad.segment<128>(128 * w).norm();
    if (norm > 0.0f) vlad.segment<128>(128 * w) /= norm;
  }
  const float norm = vlad.norm();
  if (norm > 0.0f) vlad /= norm;
  return vlad;
}

Eigen::VectorXf GlobalDescriptorModel::Whiten(const Eigen::VectorXf& vlad) const {
  EPILOC_CHECK(!empty(), "retrieval: the global descriptor model is empty");
  EPILOC_CHECK(vlad.size() == vlad_dims(), "retrieval: VLAD vector of {} values, expected {}",
               vlad.size(), vlad_dims());
  return scale_.cwiseProduct(components_ * (vlad - mean_));
}

Eigen::VectorXf GlobalDescriptorModel::Compute(const FeatureDescriptors& descriptors) const {
  EPILOC_CHECK(!empty(), "retrieval: the global descriptor model is empty");
  if (descriptors.rows() == 0) return Eigen::VectorXf::Zero(dims_);
  Eigen::VectorXf descriptor = Whiten(Vlad(descriptors));
  const float norm = descriptor.norm();
  if (norm > 0.0f) descriptor /= norm;
  return descriptor;
}

}  // namespace epiloc
