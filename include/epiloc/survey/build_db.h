// Building a route database from a survey drive: positions at frame times, SIFT on undistorted
// frames (in parallel), one transaction per frame so an interrupted build resumes where it
// stopped, the route polyline from the first drive.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "epiloc/core/progress.h"
#include "epiloc/core/types.h"
#include "epiloc/feature/sift.h"
#include "epiloc/survey/triangulate.h"

namespace epiloc {

struct BuildDbOptions {
  // Which positions annotate the frames: "auto" (ground truth if the drive has it, else GNSS),
  // "ground_truth", "gnss", or the path of a position CSV (timestamp_s, lat_deg/lon_deg/alt_m,
  // optional qw..qz: e.g. a georeferenced VO trajectory).
  std::string positions = "auto";
  // Worker threads for reading, undistorting and SIFT (0 = one per core).
  int num_threads = 0;
  SiftOptions sift;
  // Afterwards (re)build the database's whole-image retrieval index (BuildRetrievalIndex with
  // default VocabularyOptions) when this run added frames or the index is missing or stale.
  bool retrieval_index = true;
  // Afterwards (re)triangulate the database's local structure (TriangulateDatabase, replacing all
  // points) when this run added frames or the database has no points. Its num_threads 0 means
  // this build's thread count.
  bool triangulate = true;
  TriangulateOptions triangulation;

  void Check() const;
};

struct BuildDbSummary {
  drive_t drive_id = kInvalidDrive;
  std::string drive_name;
  int64_t frames_in_drive = 0;
  int64_t frames_without_position = 0;  // skipped: no position within the drive's max gap
  int64_t frames_already_present = 0;   // from an earlier (interrupted) build
  int64_t frames_added = 0;
  int64_t features_added = 0;
  // Frames added without a single SIFT feature (black, overexposed or textureless images: no
  // query frame can be placed at them); the first few are warned about one by one (with their
  // frames CSV line), all of them in one summary warning at the end.
  std::vector<frame_t> frames_without_features;
  double seconds = 0.0;
  double route_length_m = 0.0;
  bool triangulated = false;          // the triangulation step ran
  TriangulateSummary triangulation;  // its figures (seconds included in `seconds`)
};

// Adds the drive in `drive_dir` to the database at `db_path` (created if missing). Re-running adds
// no duplicates; a second drive of the same road is projected onto the route of the first.
// Throws Error for bad input; the database keeps every frame committed before the error.
BuildDbSummary BuildDatabase(const std::string& drive_dir,
                             const std::string& db_path,
                             const BuildDbOptions& options,
                             const ProgressCallback& progress = nullptr);

}  // namespace epiloc
