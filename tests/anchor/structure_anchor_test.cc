// Anchoring from structure on the synthetic street: the query drive's own VO points registered
// to the simulated LiDAR map (no photographs, no rendering), against the exact ground truth.
#include "epiloc/anchor/structure_anchor.h"

#include <algorithm>
#include <cstdio>

#include <gtest/gtest.h>

#include "anchor_test_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

struct Errors {
  int ok = 0;
  int total = 0;
  std::vector<double> horizontal_m;
  double max_horizontal_m = 0.0;
  double max_3d_m = 0.0;
  double max_rotation_deg = 0.0;
  double seconds = 0.0;
  // Of every frame with a pose, ok or rejected: the error along the road (the camera's levelled
  // viewing direction) beside the along-track sigma the anchor reports, across it, rotation.
  int posed = 0;
  std::vector<double> along_m;
  std::vector<double> along_sigma_m;
  double max_across_m = 0.0;
  double max_rotation_posed_deg = 0.0;
};

Errors Compare(const AnchorDriveResult& result, const Drive& drive, const EnuFrame& enu) {
  Errors e;
  for (const AnchorResult& a : result.frames) {
    ++e.total;
    e.seconds += a.seconds;
    if (a.status != AnchorStatus::kOk) {
      std::printf("frame %lld: %s %s\n", static_cast<long long>(a.frame),
                  AnchorStatusName(a.status).c_str(), a.message.c_str());
    }
    if (!a.has_pose) continue;
    const auto truth = TrueMapFromCam(drive, a.timestamp_s, enu);
    EXPECT_TRUE(truth.has_value());
    if (!truth) continue;
    const Eigen::Vector3d d = a.map_from_cam.translation - truth->translation;
    Eigen::Vector3d forward = truth->rotation * Eigen::Vector3d::UnitZ();
    forward.z() = 0.0;
    forward.normalize();
    const Eigen::Vector3d left = Eigen::Vector3d::UnitZ().cross(forward);
    const double rotation_deg = RotationDifferenceDeg(a.map_from_cam.rotation, truth->rotation);
    ++e.posed;
    e.along_m.push_back(d.dot(forward));
    e.along_sigma_m.push_back(a.along_sigma_m);
    e.max_across_m = std::max(e.max_across_m, std::abs(d.dot(left)));
    e.max_rotation_posed_deg = std::max(e.max_rotation_posed_deg, rotation_deg);
    // The error rotation in the map: its vertical part a turn, the rest a tilt.
    const Eigen::AngleAxisd turn(a.map_from_cam.rotation * truth->rotation.conjugate());
    std::printf(
        "frame %3lld %s: along %+.3f m (sigma %.3f m), across %+.3f m, up %+.3f m, %.3f deg (yaw "
        "%+.3f, tilt %.3f)\n",
        static_cast<long long>(a.frame), AnchorStatusName(a.status).c_str(), d.dot(forward),
        a.along_sigma_m, d.dot(left), d.z(), rotation_deg,
        turn.angle() * turn.axis().z() / kDegToRad,
        turn.angle() * turn.axis().head<2>().norm() / kDegToRad);
    if (a.status != AnchorStatus::kOk) continue;
    ++e.ok;
    e.max_horizontal_m = std::max(e.max_horizontal_m, d.head<2>().norm());
    e.horizontal_m.push_back(d.head<2>().norm());
    e.max_3d_m = std::max(e.max_3d_m, d.norm());
    e.max_rotation_deg = std::max(e.max_rotation_deg,
                                  RotationDifferenceDeg(a.map_from_cam.rotation, truth->rotation));
    std::printf(
        "frame %3lld ok: %.3f m horizontal, %.3f deg, scale %.4f (seed %.4f), %d of %d points "
        "(share %.2f), residual %.3f m, along %.3f / %.4f m, %.2f s\n",
        static_cast<long long>(a.frame), d.head<2>().norm(),
        RotationDifferenceDeg(a.map_from_cam.rotation, truth->rotation), a.scale_m_per_unit,
        a.seed_scale_m_per_unit, a.num_inliers, a.structure_points, a.inlier_share, a.residual_m,
        a.along_information, a.along_sigma_m, a.seconds);
  }
  if (e.total > 0) e.seconds /= e.total;
  return e;
}

TEST(StructureAnchor, AnchorsSyntheticQueryFromItsOwnStructure) {
  const std::string world = SharedSyntheticWorld();
  const Drive query = LoadDrive(world + "/query");
  const VoStructure vo = VoStructure::FromResult(RunVisualOdometry(query, VoOptions()));
  ASSERT_GT(vo.points.size(), 500u);
  AnchorInputs inputs;
  inputs.cloud_path = world + "/lidar/map.ply";
  inputs.map_origin = SynthOrigin();
  inputs.drive_dir = world + "/query";
  inputs.every = 4;
  StructureAnchorOptions options;
  options.prior.camera_height_m = 1.5;  // DriveOptions::Query()
  options.heading_error_deg = 5.0;
  int64_t progress_calls = 0;
  const AnchorDriveResult result =
      AnchorDriveByStructure(inputs, vo, options, [&](int64_t, int64_t) { ++progress_calls; });
  EXPECT_EQ(progress_calls, static_cast<int64_t>(result.frames.size()));
  const Errors e = Compare(result, query, EnuFrame(SynthOrigin()));
  std::printf(
      "synthetic street: %d of %d ok, horizontal max %.3f m, 3-D max %.3f m, rotation "
      "max %.3f deg, %.2f s per anchor\n",
      e.ok, e.total, e.max_horizontal_m, e.max_3d_m, e.max_rotation_deg, e.seconds);
  ASSERT_GE(e.total, 5);
  // Targets (issue 17): <= 0.05 m and 0.1 degrees: not reached. This street does not fix the
  // structure along the road: the inlier count of the fit moved along it stays within its
  // counting noise over metres, even against the world's exact surfaces or a dense 360-degree
  // LiDAR (README), so where the fit lands along the road is chance (0.2-2.3 m off). The anchors
  // say so: along_sigma_m from that profile (1.2-4 m here; the Hessian's alone said 0.03 m), and
  // all are rejected as weak along the road. Before, all 9 were ok at up to 2.26 m.
  EXPECT_EQ(e.posed, e.total);
  for (size_t i = 0; i < e.along_m.size(); ++i) {
    EXPECT_LE(std::abs(e.along_m[i]), 2.0 * e.along_sigma_m[i] + 0.1) << "posed anchor " << i;
  }
  // An anchor called ok is right (none is here); across the road and in rotation the structure
  // does place the camera (reached: 0.38 m, 0.94 deg, tied to where it lands along the road).
  if (e.ok > 0) {
    EXPECT_LE(e.max_horizontal_m, 0.3);
  }
  EXPECT_LE(e.max_across_m, 0.6);
  EXPECT_LE(e.max_rotation_posed_deg, 1.3);
}

TEST(StructureAnchor, FramesWithoutVoPoseAreLostAndBadInputThrows) {
  const std::string world = SharedSyntheticWorld();
  VoStructure vo;
  StampedPose pose;
  pose.timestamp_s = -1000.0;  // on no frame of the drive
  vo.poses.push_back(pose);
  AnchorInputs inputs;
  inputs.cloud_path = world + "/lidar/map.ply";
  inputs.map_origin = SynthOrigin();
  inputs.drive_dir = world + "/query";
  inputs.vo_path = "vo.tum";
  ExpectError([&] { AnchorDriveByStructure(inputs, vo, StructureAnchorOptions()); },
              {"vo.tum: no VO pose falls on a frame time"});
  TempDir dir;
  WriteText(dir / "vo.tum", "0 0 0 0 0 0 0 1\n");
  ExpectError([&] { VoStructure::Read(dir / "vo.tum"); }, {"vo.points.csv: no VO points file"});
  StructureAnchorOptions bad;
  bad.window_m = 0.0;
  ExpectError([&] { bad.Check(); }, {"window_m must be > 0"});
}

}  // namespace
}  // namespace epiloc
