// Helpers of the anchor tests: a small synthetic world generated once and shared by the test
// processes (CTest runs every test in its own process), and pose comparisons.
#pragma once

#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "epiloc/geo/geodetic.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/drive.h"
#include "epiloc/synth/drive_gen.h"
#include "synth_world_util.h"
#include "test_util.h"

namespace epiloc {

// The ground-truth map_from_cam of `drive` at `timestamp_s` in the ENU frame `enu`; nullopt
// without an oriented ground-truth sample there.
inline std::optional<Rigid3d> TrueMapFromCam(const Drive& drive,
                                             double timestamp_s,
                                             const EnuFrame& enu) {
  if (!drive.ground_truth) return std::nullopt;
  const auto truth = drive.ground_truth->Interpolate(timestamp_s, drive.max_gap_s);
  if (!truth || !truth->enu_from_cam) return std::nullopt;
  return Rigid3d::FromMatrix(
      enu.EnuFromLocalEnu(truth->position) * truth->enu_from_cam->toRotationMatrix(),
      enu.ToEnu(truth->position));
}

// The world's ENU origin (WorldOptions default).
inline Geodetic SynthOrigin() { return WorldOptions().origin; }

// A 50 m synthetic street with per-scan LiDAR files, survey frames every 2 m and a clean query
// (no noise, blur, exposure change or wobble; lens distortion kept) at 3 Hz, written once into
// the temporary directory and reused (the name carries the options' version). Generated into a
// private directory and renamed, so concurrent test processes never see a partial world.
inline std::string SharedSyntheticWorld() {
  SynthOptions options;
  options.length_m = 50.0;
  options.seed = 3;
  options.survey.frame_rate_hz = 4.0;
  options.query.frame_rate_hz = 3.0;
  options.query.render = options.survey.render;
  options.query.exposure_s = 0.0;
  options.query.wobble_yaw_deg = 0.0;
  options.query.wobble_pitch_deg = 0.0;
  options.lidar_scan_files = true;
  return SharedWorld("epiloc_anchor_test_world_v1", options);
}

}  // namespace epiloc
