// Helpers of the survey-chain tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

#include "epiloc/anchor/anchor.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/georef/anchors.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/result.h"

namespace epiloc {

// The ok frames of an anchoring run as georeferencing anchors (what `epiloc georef` reads from
// the anchor CSV, the structure anchors' scale included).
inline AnchorSet OkAnchors(const AnchorDriveResult& anchored) {
  AnchorSet anchors;
  anchors.path = "anchors";
  for (const AnchorResult& a : anchored.frames) {
    if (a.status != AnchorStatus::kOk) continue;
    Anchor anchor;
    anchor.frame = a.frame;
    anchor.timestamp_s = a.timestamp_s;
    anchor.position = a.position;
    anchor.enu_from_cam = a.enu_from_cam;
    if (std::isfinite(a.scale_m_per_unit) && a.scale_m_per_unit > 0.0) {
      anchor.scale_m_per_unit = a.scale_m_per_unit;
    }
    anchors.anchors.push_back(anchor);
  }
  return anchors;
}

// Largest horizontal error of the ok rows of `method` against the drive's ground truth.
inline double MaxHorizontal(const ResultTable& table,
                            const std::string& method,
                            const Drive& drive) {
  const EnuFrame enu(drive.ground_truth->samples.front().position);
  double worst = 0.0;
  for (const ResultRow& r : table.rows) {
    if (r.method != method || r.status != ResultStatus::kOk) continue;
    const auto truth = drive.ground_truth->Interpolate(r.timestamp_s, drive.max_gap_s);
    if (!truth) continue;
    worst = std::max(worst, (enu.ToEnu(r.position) - enu.ToEnu(truth->position)).head<2>().norm());
  }
  return worst;
}

// Largest rotation error (degrees) of the ok rows of `method` with an orientation against the
// drive's ground truth (local ENU at each camera on both sides; the frames' convergence over a
// street is far below the errors measured).
inline double MaxRotationDeg(const ResultTable& table,
                             const std::string& method,
                             const Drive& drive) {
  double worst = 0.0;
  for (const ResultRow& r : table.rows) {
    if (r.method != method || r.status != ResultStatus::kOk || !r.enu_from_cam) continue;
    const auto truth = drive.ground_truth->Interpolate(r.timestamp_s, drive.max_gap_s);
    if (!truth || !truth->enu_from_cam) continue;
    worst = std::max(worst, RotationDifferenceDeg(*r.enu_from_cam, *truth->enu_from_cam));
  }
  return worst;
}

}  // namespace epiloc
