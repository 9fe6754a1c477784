// Running a Localizer over a frame source: extraction of the next frames runs ahead on other
// threads while the tracker works on the current one; each frame's rows are handed over as soon
// as it is tracked, the offline rows at the end of the input.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "epiloc/core/csv.h"
#include "epiloc/core/progress.h"
#include "epiloc/io/result.h"
#include "epiloc/localize/frame_source.h"
#include "epiloc/localize/localizer.h"

namespace epiloc {

// What a run did and how fast.
struct LocalizeRun {
  ResultTable results;  // every row (Localize only; LocalizeStream hands rows to its sink)
  int num_frames = 0;
  int num_localized_online = 0;
  int num_skipped = 0;  // late frames skipped (LocalizeOptions::max_latency_s)
  int num_reinitialisations = 0;
  int64_t num_pairs = 0;
  bool refined = false;         // pnp rows were written (the database has structure)
  int num_refined_ok = 0;       // frames with an accepted PnP pose
  int num_refine_thin = 0;      // fell back to the epipolar estimate: too little structure
  int num_refine_rejected = 0;  // fell back: the PnP pose disagreed with the sequence
  double seconds = 0.0;         // wall-clock time of the whole run
  double frames_per_second = 0.0;
  // Per stage, summed over frames (extraction runs on other threads, so these overlap).
  double extraction_seconds = 0.0;  // undistortion, SIFT, retrieval descriptor
  double tracking_seconds = 0.0;    // matching, epipoles, DTW, V-fit, refinement
  StageSeconds stages;              // the same split by stage, summed over frames
  double maintenance_seconds = 0.0;  // Localizer::Maintain between frames (in stages.window)
  // Per tracked frame, from the frame's arrival (FrameSource) to its rows handed to the sink.
  double latency_p50_s = 0.0, latency_p95_s = 0.0, latency_max_s = 0.0;
  // Frames whose image gave no SIFT features (black, overexposed, textureless), in order.
  std::vector<frame_t> frames_without_features;
};

// Called for each tracked frame with its estimate and rows, in frame order, as soon as they are
// ready; then once with estimate = nullptr and the offline rows (when the options ask for them).
using RowSink =
    std::function<void(const FrameEstimate* estimate, const std::vector<ResultRow>& rows)>;

// Runs `localizer` over every frame of `source` until the source ends. At most
// options().num_threads frames are prepared ahead. `progress` gets (frames done, source size or
// 0). Rethrows the first error of the source, the extraction or the tracker. A frame without SIFT
// features is warned about (naming its frames CSV line) for the first kFeaturelessWarnings such
// frames; when any, one summary warning at the end counts them all.
constexpr int kFeaturelessWarnings = 3;
LocalizeRun LocalizeStream(Localizer& localizer,
                           FrameSource& source,
                           const RowSink& sink,
                           const ProgressCallback& progress = nullptr);

// Localizes every frame of the drive in `drive_dir` against the database and collects the rows
// (online rows per frame, then the offline ones). Throws Error for bad input; frames that cannot
// be localized are rows with status lost / off_route.
LocalizeRun Localize(const std::string& db_path,
                     const std::string& drive_dir,
                     const LocalizeOptions& options,
                     const ProgressCallback& progress = nullptr);

// Per-pair diagnostics CSV (--diagnostics), one row per evaluated pair, written frame by frame
// (the localizer's options need `diagnostics` on). Copies the database frame numbers and
// positions it needs from the localizer.
class DiagnosticsCsv {
 public:
  DiagnosticsCsv(const std::string& path, const Localizer& localizer);
  void Write(const FrameEstimate& estimate);
  void Close();

 private:
  std::vector<frame_t> db_frame_numbers_;
  std::vector<double> db_s_m_;
  CsvWriter out_;
};

}  // namespace epiloc
