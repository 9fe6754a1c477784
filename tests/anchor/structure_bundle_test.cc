// The map bundle (StructureAnchorOptions::map_bundle) on an exact street: a corridor of two
// facades and a ground plane, cameras along it, points on its surfaces seen without noise.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/core/angles.h"
#include "structure_anchor_internal.h"
#include "test_util.h"

namespace epiloc {
namespace {

constexpr double kFocalPx = 500.0;

// The corridor: facades at x = -6 and x = +6 m (0 to 8 m high), the ground at z = 0, the road
// along +y; cameras 1.5 m high in the right lane (x = +1.5), one per metre, looking along +y.
constexpr double kPillarStart = 2.3;  // the first pillar front at or above y = 0, metres

struct Corridor {
  Drive drive;  // not read by the bundle
  std::vector<size_t> indices = {0};
  std::vector<int> pose_of;
  VoStructure vo;
  PointCloud map;
  EnuFrame map_frame{Geodetic{49.0, 8.4, 110.0}};
  StructureAnchorOptions options;

  // `pillars`: also pillars standing out of both facades, 0.5 m deep and 1 m wide, every 6 m:
  // their fronts face along the road and fix it.
  Corridor(int cameras, int anchor_pose, bool pillars = false) {
    pose_of = {anchor_pose};
    Eigen::Matrix3d world_from_cam;  // x right, y down, z forward
    world_from_cam << 1, 0, 0,       //
        0, 0, 1,                     //
        0, -1, 0;
    for (int i = 0; i < cameras; ++i) {
      StampedPose pose;
      pose.frame = i;
      pose.timestamp_s = i;
      pose.world_from_cam =
          Rigid3d(Eigen::Quaterniond(world_from_cam), Eigen::Vector3d(1.5, i, 1.5));
      vo.poses.push_back(pose);
    }
    vo.observation_focal_px = kFocalPx;
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double y_lo = -10.0, y_hi = cameras + 30.0;
    // A pillar's front (facing -y) at y = kPillarStart + 6 k, x from the facade 0.5 m inwards,
    // 0 to 3 m high.
    const auto pillar_front = [](double y) { return kPillarStart + 6.0 * std::floor(y / 6.0); };
    for (int n = 0; n < 3000; ++n) {
      const int surface = n % (pillars ? 4 : 3);
      const double y = y_lo + (y_hi - y_lo) * u(rng);
      Eigen::Vector3d x;
      if (surface == 3) {
        const double side = u(rng) < 0.5 ? -1.0 : 1.0;
        x = Eigen::Vector3d(side * (5.5 + 0.5 * u(rng)), pillar_front(y), 3.0 * u(rng));
      } else {
        x = surface == 2 ? Eigen::Vector3d(-6.0 + 12.0 * u(rng), y, 0.0)
                         : Eigen::Vector3d(surface == 0 ? -6.0 : 6.0, y, 8.0 * u(rng));
      }
      VoPoint p;
      p.point_in_world = x;
      for (const StampedPose& pose : vo.poses) {
        const Eigen::Vector3d c = pose.world_from_cam.Inverse() * x;
        if (c.z() < 1.0 || c.z() > 35.0) continue;
        const Eigen::Vector2d xy = c.head<2>() / c.z();
        if (std::abs(xy.x()) > 1.0 || std::abs(xy.y()) > 0.4) continue;  // 1000 x 400 pixels
        p.seen.push_back({pose.frame, xy});
      }
      if (p.seen.size() < 2) continue;
      p.first_frame = p.seen.front().frame;
      p.last_frame = p.seen.back().frame;
      p.observations = static_cast<int>(p.seen.size());
      vo.points.push_back(p);
    }
    // The map: the same surfaces every 0.2 m.
    for (double y = y_lo; y <= y_hi; y += 0.2) {
      for (double s = 0.0; s <= 8.0; s += 0.2) {
        map.positions.emplace_back(-6.0f, static_cast<float>(y), static_cast<float>(s));
        map.positions.emplace_back(6.0f, static_cast<float>(y), static_cast<float>(s));
      }
      for (double s = -6.0; s <= 6.0; s += 0.2) {
        map.positions.emplace_back(static_cast<float>(s), static_cast<float>(y), 0.0f);
      }
    }
    for (double y = pillar_front(y_lo); pillars && y <= y_hi; y += 6.0) {
      for (double z = 0.0; z <= 3.0; z += 0.2) {
        for (double d = 0.0; d <= 0.5; d += 0.1) {
          for (const double side : {-1.0, 1.0}) {
            map.positions.emplace_back(static_cast<float>(side * (6.0 - d)), static_cast<float>(y),
                                       static_cast<float>(z));
          }
        }
      }
    }
    options.map_voxel_m = 0.0;
    options.bundle_window_m = 39.0;  // cameras 1 to 39 about camera 20
  }

  structure_internal::MapLoader Loader() const {
    return [this](const Eigen::Vector3d&, double) { return map; };
  }

  // The anchor as the passes left it: at the true centre, its rotation `turn` off the truth.
  AnchorResult Anchor(const Eigen::Quaterniond& turn) const {
    AnchorResult a;
    a.has_pose = true;
    a.status = AnchorStatus::kOk;
    a.scale_m_per_unit = 1.0;
    const Rigid3d& truth = vo.poses[static_cast<size_t>(pose_of[0])].world_from_cam;
    a.map_from_cam.rotation = turn * truth.rotation;
    a.map_from_cam.translation = truth.translation;
    return a;
  }
};

// An anchor whose rotation is 0.3 degrees off (its whole window turned with it about its
// camera): the bundle turns it back to the truth, in every axis. Not to the last digit: the
// map's planes where the facades meet the ground are its points' PCA (a bent normal), 0.001 deg.
TEST(StructureBundle, RecoversTheCameraRotationOnAnExactStreet) {
  Corridor c(41, 20);
  const structure_internal::MapLoader load = c.Loader();
  const structure_internal::DriveAnchoring run{c.drive, c.indices,   c.pose_of, c.vo,
                                               load,    c.map_frame, c.options};
  const Eigen::Quaterniond truth = c.vo.poses[20].world_from_cam.rotation;
  const std::vector<Eigen::Vector3d> axes = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
                                             Eigen::Vector3d::UnitZ(), Eigen::Vector3d(1, 1, 1)};
  for (const Eigen::Vector3d& axis : axes) {
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.3 * kDegToRad, axis.normalized()));
    const AnchorResult a = c.Anchor(turn);
    EXPECT_NEAR(RotationDifferenceDeg(a.map_from_cam.rotation, truth), 0.3, 1e-9);
    const structure_internal::MapBundleResult b = structure_internal::AdjustWindowToMap(run, 0, a);
    ASSERT_TRUE(b.success);
    EXPECT_LT(RotationDifferenceDeg(b.map_from_cam, truth), 0.002) << axis.transpose();
    EXPECT_EQ(b.cameras, 39);
    EXPECT_GT(b.points_on_map, 1000);
  }
  // Three anchors adjusted together, each turned its own way (their windows placed by their own
  // similarities, so the start is not one rigid structure): each turned back.
  c.indices = {0, 1, 2};
  c.pose_of = {10, 20, 30};
  const structure_internal::DriveAnchoring three{c.drive, c.indices,   c.pose_of, c.vo,
                                                 load,    c.map_frame, c.options};
  std::vector<AnchorResult> anchors;
  for (int i = 0; i < 3; ++i) {
    AnchorResult a = c.Anchor(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * kDegToRad, axes[i])));
    const Rigid3d& at = c.vo.poses[static_cast<size_t>(c.pose_of[i])].world_from_cam;
    a.map_from_cam.translation = at.translation;
    a.map_from_cam.rotation = Eigen::AngleAxisd(0.3 * kDegToRad, axes[i]) * at.rotation;
    anchors.push_back(a);
  }
  const std::vector<structure_internal::MapBundleResult> together =
      structure_internal::AdjustWindowsToMap(three, {0, 1, 2}, anchors);
  ASSERT_EQ(together.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(together[i].success);
    EXPECT_LT(RotationDifferenceDeg(
                  together[i].map_from_cam,
                  c.vo.poses[static_cast<size_t>(c.pose_of[i])].world_from_cam.rotation),
              0.005)
        << i;
    EXPECT_EQ(together[i].cameras, 41);  // 10 - 19.5 to 30 + 19.5: every camera
  }
  c.indices = {0};
  c.pose_of = {20};
  // The pass: the anchor takes the rotation; its centre, which nothing on this street fixes along
  // the road, stays where the prior holds it (0.6 mm: the window is turned back about its points
  // on the map, not exactly about the camera).
  AnchorDriveResult result;
  result.frames.push_back(
      c.Anchor(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * kDegToRad, Eigen::Vector3d::UnitZ()))));
  const Eigen::Vector3d centre = result.frames[0].map_from_cam.translation;
  structure_internal::RefineByMapBundle(run, &result);
  EXPECT_LT(RotationDifferenceDeg(result.frames[0].map_from_cam.rotation, truth), 0.002);
  EXPECT_LT((result.frames[0].map_from_cam.translation - centre).norm(), 0.002);
  EXPECT_LT(result.frames[0].bundle_move_m, 0.002);
}

// An ok anchor placed 0.2 m too far along the road (its whole window with it, as a structure bent
// by the VO's poses leaves it): where surfaces face along the road (the pillars' fronts), the
// bundle puts its camera back, against the prior that holds it within 0.15 m of its placement.
// A rejected anchor is doubted and keeps its place; its height is the registration's either way.
TEST(StructureBundle, OkAnchorsTakeTheCentreTheImagesAndTheMapGive) {
  Corridor c(41, 20, /*pillars=*/true);
  const structure_internal::MapLoader load = c.Loader();
  const structure_internal::DriveAnchoring run{c.drive, c.indices,   c.pose_of, c.vo,
                                               load,    c.map_frame, c.options};
  const Eigen::Vector3d truth = c.vo.poses[20].world_from_cam.translation;
  const Eigen::Vector3d off(0.0, 0.2, 0.0);
  AnchorResult a = c.Anchor(Eigen::Quaterniond::Identity());
  a.map_from_cam.translation += off;
  const structure_internal::MapBundleResult b = structure_internal::AdjustWindowToMap(run, 0, a);
  ASSERT_TRUE(b.success);
  EXPECT_LT((b.centre - truth).norm(), 0.002) << b.centre.transpose();  // 0.4 mm

  AnchorDriveResult result;
  result.frames.push_back(a);
  structure_internal::RefineByMapBundle(run, &result);
  const AnchorResult& moved = result.frames[0];
  EXPECT_LT((moved.map_from_cam.translation - truth).head<2>().norm(), 0.002);
  EXPECT_EQ(moved.map_from_cam.translation.z(), a.map_from_cam.translation.z());
  EXPECT_NEAR(moved.bundle_move_m, 0.2, 0.002);

  // Without the pillars nothing fixes it along the road: the prior keeps it where it was placed.
  Corridor plain(41, 20);
  const structure_internal::MapLoader plain_load = plain.Loader();
  const structure_internal::DriveAnchoring plain_run{plain.drive,  plain.indices, plain.pose_of,
                                                     plain.vo,     plain_load,    plain.map_frame,
                                                     plain.options};
  const structure_internal::MapBundleResult free =
      structure_internal::AdjustWindowToMap(plain_run, 0, a);
  ASSERT_TRUE(free.success);
  EXPECT_LT((free.centre - (truth + off)).norm(), 0.002) << free.centre.transpose();

  // Rejected: the rotation only.
  result.frames[0] = a;
  result.frames[0].status = AnchorStatus::kRejected;
  structure_internal::RefineByMapBundle(run, &result);
  EXPECT_EQ(result.frames[0].map_from_cam.translation, a.map_from_cam.translation);
  EXPECT_TRUE(std::isnan(result.frames[0].bundle_move_m));
}

// A rejected anchor among ok ones (metres off along the road and turned by degrees, as a
// registration on another facade period leaves it) neither places the cameras and points around
// it nor holds the gauge: the ok anchors are turned back as without it; it takes the rotation of
// its frame's camera, placed by them, and keeps its centre.
// (Taken into the bundle, its similarity bent the window: on a synthetic street 25 ok anchors
// took 2-4 degrees of yaw from the rejected ones between them.)
TEST(StructureBundle, RejectedAnchorsTakeTheirCameraRotationOnly) {
  Corridor c(41, 20);
  c.indices = {0, 1, 2};
  c.pose_of = {10, 20, 30};
  const structure_internal::MapLoader load = c.Loader();
  const structure_internal::DriveAnchoring run{c.drive, c.indices,   c.pose_of, c.vo,
                                               load,    c.map_frame, c.options};
  AnchorDriveResult result;
  for (int i = 0; i < 3; ++i) {
    const Rigid3d& at = c.vo.poses[static_cast<size_t>(c.pose_of[i])].world_from_cam;
    AnchorResult a = c.Anchor(Eigen::Quaterniond::Identity());
    a.map_from_cam.translation = at.translation;
    a.map_from_cam.rotation =
        Eigen::AngleAxisd(0.3 * kDegToRad, Eigen::Vector3d::UnitZ()) * at.rotation;
    if (i == 1) {
      a.status = AnchorStatus::kRejected;
      a.map_from_cam.translation += Eigen::Vector3d(0.0, 5.0, 0.0);
      a.map_from_cam.rotation =
          Eigen::AngleAxisd(3.0 * kDegToRad, Eigen::Vector3d::UnitZ()) * at.rotation;
    }
    result.frames.push_back(a);
  }
  const AnchorResult rejected = result.frames[1];
  structure_internal::RefineByMapBundle(run, &result);
  for (const int i : {0, 2}) {
    EXPECT_LT(RotationDifferenceDeg(
                  result.frames[static_cast<size_t>(i)].map_from_cam.rotation,
                  c.vo.poses[static_cast<size_t>(c.pose_of[i])].world_from_cam.rotation),
              0.005)
        << i;
  }
  EXPECT_LT(RotationDifferenceDeg(result.frames[1].map_from_cam.rotation,
                                  c.vo.poses[20].world_from_cam.rotation),
            0.005);
  EXPECT_EQ(result.frames[1].map_from_cam.translation, rejected.map_from_cam.translation);
}

// Nothing to adjust: no sightings (the VO's own points), no pose, no map, a window of one camera.
TEST(StructureBundle, LeavesTheAnchorWithoutSightingsPoseOrMap) {
  Corridor c(41, 20);
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.3 * kDegToRad, Eigen::Vector3d::UnitZ()));
  const structure_internal::MapLoader load = c.Loader();
  {
    VoStructure unseen = c.vo;
    for (VoPoint& p : unseen.points) p.seen.clear();
    const structure_internal::DriveAnchoring run{c.drive, c.indices,   c.pose_of, unseen,
                                                 load,    c.map_frame, c.options};
    EXPECT_FALSE(structure_internal::AdjustWindowToMap(run, 0, c.Anchor(turn)).success);
    AnchorDriveResult result;
    result.frames.push_back(c.Anchor(turn));
    const AnchorResult before = result.frames[0];
    structure_internal::RefineByMapBundle(run, &result);
    EXPECT_TRUE(result.frames[0].map_from_cam.rotation.isApprox(before.map_from_cam.rotation));
  }
  const structure_internal::DriveAnchoring run{c.drive, c.indices,   c.pose_of, c.vo,
                                               load,    c.map_frame, c.options};
  AnchorResult unposed = c.Anchor(turn);
  unposed.has_pose = false;
  EXPECT_FALSE(structure_internal::AdjustWindowToMap(run, 0, unposed).success);
  const structure_internal::MapLoader empty = [](const Eigen::Vector3d&, double) {
    return PointCloud();
  };
  const structure_internal::DriveAnchoring no_map{c.drive, c.indices,   c.pose_of, c.vo,
                                                  empty,   c.map_frame, c.options};
  EXPECT_FALSE(structure_internal::AdjustWindowToMap(no_map, 0, c.Anchor(turn)).success);
  StructureAnchorOptions short_window = c.options;
  short_window.bundle_window_m = 0.5;
  const structure_internal::DriveAnchoring one{c.drive, c.indices,   c.pose_of,   c.vo,
                                               load,    c.map_frame, short_window};
  EXPECT_FALSE(structure_internal::AdjustWindowToMap(one, 0, c.Anchor(turn)).success);
}

TEST(StructureBundle, BadOptionsThrow) {
  StructureAnchorOptions options;
  options.bundle_window_m = 0.0;
  ExpectError([&] { options.Check(); }, {"bundle_window_m must be > 0"});
  options = StructureAnchorOptions();
  options.bundle_distances_m.clear();
  ExpectError([&] { options.Check(); }, {"bundle_distances_m is empty"});
  options.bundle_distances_m = {0.5, NAN};
  ExpectError([&] { options.Check(); }, {"bundle_distances_m must be > 0"});
  options = StructureAnchorOptions();
  options.bundle_plane_sigma_m = -1.0;
  ExpectError([&] { options.Check(); }, {"bundle_plane_sigma_m must be > 0"});
  options = StructureAnchorOptions();
  options.bundle_chunk_m = -1.0;
  ExpectError([&] { options.Check(); }, {"bundle_chunk_m must be >= 0"});
  options = StructureAnchorOptions();
  options.bundle_iterations = 0;
  ExpectError([&] { options.Check(); }, {"bundle_iterations must be >= 1"});
  options = StructureAnchorOptions();
  options.bundle_huber_px = 0.0;
  ExpectError([&] { options.Check(); }, {"bundle_huber_px must be > 0"});
  options = StructureAnchorOptions();
  options.bundle_centre_sigma_m = NAN;
  ExpectError([&] { options.Check(); }, {"bundle_centre_sigma_m must be > 0"});
}

}  // namespace
}  // namespace epiloc
