// The route database's whole-image retrieval index: the retrieval model trained on the database's
// own frames and one global descriptor per frame (db_schema/0002_global_descriptors.sql), so a
// query frame can be placed on the route without a position prior
// (epiloc/retrieval/global_descriptor.h).
#pragma once

#include <cstdint>
#include <string>

#include "epiloc/core/progress.h"
#include "epiloc/db/database.h"
#include "epiloc/retrieval/global_descriptor.h"

namespace epiloc {

struct RetrievalIndexSummary {
  // False when the database has too few frames (< 2) or features (< num_words) to train a model;
  // `reason` says which, and the database then holds no retrieval index at all.
  bool built = false;
  std::string reason;
  int64_t num_frames = 0;       // frames given a global descriptor
  int num_training_images = 0;  // frames the model was trained on
  int num_words = 0;
  int dims = 0;  // of each global descriptor
  double seconds = 0.0;
};

// Trains the retrieval model on the database's frames (an even subsample of at most
// options.max_training_images, reading only their strongest options.features_per_image
// descriptors, so memory stays bounded for any database size), stores it, and computes and stores
// every frame's global descriptor, replacing any earlier model and descriptors. One transaction:
// call it outside Database::Transaction; an error leaves the previous index in place. `progress`
// gets (frames read, training frames + all frames). Throws Error for database failures and
// degenerate training data (identical images).
RetrievalIndexSummary BuildRetrievalIndex(Database& db,
                                          const VocabularyOptions& options,
                                          const ProgressCallback& progress = nullptr);

// True when the database holds a retrieval model and a global descriptor for every frame (frames
// added since the last BuildRetrievalIndex make it stale).
bool HasCurrentRetrievalIndex(const Database& db);

// The stored global descriptors as a searchable index (ids = image_id), and the model that
// computes query descriptors into `model` (unless null). Throws Error naming the database if it
// has no retrieval model, the model blob is corrupt, or a descriptor's size differs from the
// model's.
GlobalIndex LoadRetrievalIndex(const Database& db, GlobalDescriptorModel* model);

}  // namespace epiloc
