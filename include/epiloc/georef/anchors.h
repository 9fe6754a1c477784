// Anchors: frames whose absolute pose is known (from `epiloc anchor`: rendered LiDAR, matching,
// PnP; Kurobe et al.), as rows of a result CSV (eval/result.h) with method `anchor`, and a
// simulation of them from a drive's ground truth for development and tests.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "epiloc/core/types.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/result.h"

namespace epiloc {

// One usable anchor: the camera's absolute pose at a frame time.
struct Anchor {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  Geodetic position;                               // camera centre
  std::optional<Eigen::Quaterniond> enu_from_cam;  // local ENU at `position`
  // The anchor's own scale of the trajectory it was anchored on (metres per VO unit; column
  // scale_m_per_unit, which `epiloc anchor --method structure` writes), when the file has one.
  std::optional<double> scale_m_per_unit;
  // The VO's scale drift the anchor's fit applied (relative change of scale per metre of road,
  // positive: growing with time; column scale_drift_per_m, `epiloc anchor --method structure`),
  // when the file has one.
  std::optional<double> scale_drift_per_m;
  int64_t line = 0;  // of the anchors file
};

struct AnchorSet {
  std::string path;
  std::vector<Anchor> anchors;  // status ok rows of the method, by time
  int64_t rows_not_ok = 0;      // rows of the method with another status (rejected, lost, ...)
};

// Reads the rows of `method` (default "anchor") of a result CSV; only status ok rows become
// anchors. Throws Error naming the file for no rows of the method or repeated timestamps (and the
// result-CSV errors of ReadResultCsv).
AnchorSet ReadAnchors(const std::string& path, const std::string& method = "anchor");

// Simulated anchors from ground truth: every `step`-th frame (from `first`) of a drive with
// ground truth, with Gaussian errors: `position_sigma_m` per ENU axis and a rotation error of
// `rotation_sigma_deg` per axis (a rotation vector applied in the camera frame).
struct AnchorSimulationOptions {
  int64_t step = 10;              // frames between anchors
  int64_t first = 0;              // index (in drive order) of the first anchored frame
  double position_sigma_m = 0.0;  // per axis
  double rotation_sigma_deg = 0.0;
  uint64_t seed = 1;

  // Throws Error naming the invalid field.
  void Check() const;
};

// Result rows of method "anchor", status ok, with orientation; frames without ground truth (or
// without orientation in it) are skipped. Throws Error if the drive has no ground truth with
// orientations.
ResultTable SimulateAnchors(const Drive& drive, const AnchorSimulationOptions& options);

}  // namespace epiloc
