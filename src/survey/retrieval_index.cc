#include "epiloc/survey/retrieval_index.h"

#include <algorithm>
#include <chrono>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "epiloc/core/error.h"

namespace epiloc {

RetrievalIndexSummary BuildRetrievalIndex(Database& db,
                                          const VocabularyOptions& options,
                                          const ProgressCallback& progress) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  RetrievalIndexSummary summary;
  Database::Transaction transaction(db);
  const std::vector<DbFrame> frames = db.ReadFrames();

  // The same even spread Train() would pick, read here so only these frames are held in memory.
  std::vector<size_t> chosen;
  const size_t num_chosen =
      std::min(frames.size(), static_cast<size_t>(options.max_training_images));
  for (size_t j = 0; j < num_chosen; ++j) chosen.push_back(j * frames.size() / num_chosen);
  const int64_t total = static_cast<int64_t>(chosen.size() + frames.size());
  int64_t done = 0;

  std::vector<FeatureDescriptors> training;
  int64_t num_descriptors = 0;
  for (const size_t i : chosen) {
    FeatureDescriptors descriptors = db.ReadDescriptors(frames[i].image_id);
    const Eigen::Index rows =
        std::min<Eigen::Index>(descriptors.rows(), options.features_per_image);
    training.emplace_back(descriptors.topRows(rows));
    num_descriptors += rows;
    if (progress) progress(++done, total);
  }
  if (frames.size() < 2) {
    summary.reason = fmt::format("{} frames, at least 2 are needed", frames.size());
  } else if (num_descriptors < options.num_words) {
    summary.reason =
        fmt::format("{} features for a vocabulary of {} words", num_descriptors, options.num_words);
  }
  db.ClearGlobalDescriptors();
  if (!summary.reason.empty()) {
    db.DeleteRetrievalModel();  // a stale model must not outlive its descriptors
    transaction.Commit();
    return summary;
  }

  std::vector<const FeatureDescriptors*> pointers;
  for (const FeatureDescriptors& descriptors : training) pointers.push_back(&descriptors);
  const GlobalDescriptorModel model = GlobalDescriptorModel::Train(pointers, options);
  pointers.clear();
  training.clear();
  db.WriteRetrievalModel(model.Serialize(), model.num_words(), model.dims());

  std::vector<float> values(model.dims());
  for (const DbFrame& frame : frames) {
    const Eigen::VectorXf descriptor = model.Compute(db.ReadDescriptors(frame.image_id));
    std::copy(descriptor.data(), descriptor.data() + descriptor.size(), values.begin());
    db.WriteGlobalDescriptor(frame.image_id, values);
    if (progress) progress(++done, total);
  }
  transaction.Commit();

  summary.built = true;
  summary.num_frames = static_cast<int64_t>(frames.size());
  summary.num_training_images = static_cast<int>(chosen.size());
  summary.num_words = model.num_words();
  summary.dims = model.dims();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

bool HasCurrentRetrievalIndex(const Database& db) {
  return db.NumGlobalDescriptors() == db.NumFrames() && db.ReadRetrievalModel().has_value();
}

GlobalIndex LoadRetrievalIndex(const Database& db, GlobalDescriptorModel* model) {
  const std::optional<std::vector<uint8_t>> bytes = db.ReadRetrievalModel();
  EPILOC_CHECK(bytes.has_value(), "{}: no retrieval index in the database (build-db builds it)",
               db.path());
  GlobalDescriptorModel loaded;
  try {
    loaded = GlobalDescriptorModel::Deserialize(*bytes);
  } catch (const Error& error) {
    Throw("{}: {}", db.path(), error.what());
  }
  const auto descriptors = db.ReadGlobalDescriptors();
  GlobalIndex index;
  index.Reserve(static_cast<int64_t>(descriptors.size()));
  for (const auto& [image_id, values] : descriptors) {
    EPILOC_CHECK(static_cast<int>(values.size()) == loaded.dims(),
                 "{}: global descriptor of image {} has {} values, the retrieval model {}",
                 db.path(), image_id, values.size(), loaded.dims());
    index.Add(image_id, Eigen::Map<const Eigen::VectorXf>(values.data(), values.size()));
  }
  if (model != nullptr) *model = std::move(loaded);
  return index;
}

}  // namespace epiloc
