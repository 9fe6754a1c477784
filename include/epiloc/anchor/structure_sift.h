// Structure for anchoring (`epiloc anchor --vo ... --structure sift`; the default, `--structure
// vo`, registers the VO's own KLT points): the drive's own SIFT features matched between
// neighbouring frames and triangulated along its VO poses, in place of the VO's KLT points.
//
// The VO's poses are good (synthetic street: 0.008 m median under the true similarity) but its
// points are not: a KLT track drifts over its length and its depth comes from few keyframes
// (median 0.22 m from the world's surfaces, 0.48 m for tracks of 10+ keyframes). The survey's
// triangulation (survey/triangulate.h: SIFT matches with the poses' epipolar check, multi-view
// tracks, reprojection refinement) along the same poses gives structure the map can place: on
// the synthetic street, with the true similarity, the count of points on the map's surfaces
// peaks at the truth where the KLT points' is flat (README "Anchoring from structure").
//
// How: per VO segment, the poses are mapped by a similarity into a metric, levelled local frame
// (scale from the GNSS track's length over the VO's, the segment's first camera level and
// looking north), written as a position CSV, and the drive's frames are built into a temporary
// route database with them (survey/build_db.h: SIFT, then triangulation); its points come back
// into the VO world, with the drive frames that saw them.
#pragma once

#include <string>

#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/core/progress.h"
#include "epiloc/survey/build_db.h"

namespace epiloc {

struct SiftStructureSummary {
  int segments = 0;    // VO segments triangulated
  int frames = 0;      // frames with a VO pose used
  int64_t points = 0;  // points triangulated
  double mean_track_length = 0.0;
  double seconds = 0.0;
};

// `vo` with its points replaced by SIFT points triangulated along its poses (see the top of the
// file); poses and segments unchanged. `build` sets SIFT, triangulation and threads (its
// positions, retrieval index and triangulate flag are set here). Segments with fewer than two
// posed frames or no GNSS scale are skipped. Throws Error for an unreadable drive or a failed
// build (the temporary database is removed either way).
VoStructure TriangulateAlongVo(const std::string& drive_dir,
                               const VoStructure& vo,
                               const BuildDbOptions& build,
                               SiftStructureSummary* summary = nullptr,
                               const ProgressCallback& progress = nullptr);

}  // namespace epiloc
