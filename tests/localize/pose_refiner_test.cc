#include "epiloc/localize/pose_refiner.h"

#include <algorithm>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "epiloc/geo/rigid3.h"
#include "test_util.h"

namespace epiloc {
namespace {

Camera KittiLikeCamera() {
  Camera c;
  c.width = 1242;
  c.height = 375;
  c.fx = c.fy = 721.5377;
  c.cx = 609.5593;
  c.cy = 172.854;
  return c;
}

// A straight route along north, a camera on it looking north (x east, y down, z north).
struct Scene {
  Route route{{{0, 0, 0}, {0, 100, 0}}};
  Camera camera = KittiLikeCamera();
  Rigid3d enu_from_cam;
  FeatureKeypoints keypoints;
  std::vector<PairResult> pairs;
};

// `n` points on facades 6-10 m left and right of the road, seen by the camera at (lateral, s, 1.6)
// with a small yaw; their exact projections become query keypoints; the matches are spread
// over 3 database pairs, each point seen by 1-2 of them (as in the localizer).
Scene MakeScene(int n, double s_true, double lateral, uint32_t seed) {
  Scene scene;
  const double yaw = 0.02;  // rad
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d(std::cos(yaw), -std::sin(yaw), 0);  // camera x: east (right)
  r.col(1) = Eigen::Vector3d(0, 0, -1);                          // y: down
  r.col(2) = Eigen::Vector3d(std::sin(yaw), std::cos(yaw), 0);   // z: north (forward)
  scene.enu_from_cam = Rigid3d::FromMatrix(r, Eigen::Vector3d(lateral, s_true, 1.6));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> along(s_true + 5, s_true + 40), height(0.0, 6.0),
      side(6.0, 10.0);
  const Rigid3d cam_from_enu = scene.enu_from_cam.Inverse();
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  while (static_cast<int>(points.size()) < n) {
    const double x = (points.size() % 2 ? 1 : -1) * side(rng);
    const Eigen::Vector3d p(x, along(rng), height(rng));
    const Eigen::Vector3d c = cam_from_enu * p;
    if (c.z() <= 1) continue;
    const Eigen::Vector2d uv = scene.camera.Project(c);
    if (uv.x() < 0 || uv.y() < 0 || uv.x() > scene.camera.width - 1 ||
        uv.y() > scene.camera.height - 1) {
      continue;
    }
    pixels.push_back(uv);
    points.push_back(p);
  }
  scene.keypoints.resize(n, 4);
  scene.pairs.resize(3);
  for (int i = 0; i < n; ++i) {
    scene.keypoints.row(i) << static_cast<float>(pixels[i].x()), static_cast<float>(pixels[i].y()),
        3.0f, 0.0f;
    scene.pairs[i % 3].point_matches.push_back({i, 1000 + i, points[i]});
    if (i % 2 == 0) scene.pairs[(i + 1) % 3].point_matches.push_back({i, 1000 + i, points[i]});
  }
  return scene;
}

TEST(PoseRefiner, RecoversTheExactPoseFromItsCorrespondences) {
  // Keypoints are float (as stored), so exact means: within what float pixels allow.
  const Scene scene = MakeScene(200, 30.0, 1.2, 1);
  const PoseRefinement r =
      RefinePose(scene.camera, scene.keypoints, scene.pairs, 30.3, scene.route, RefineOptions());
  ASSERT_EQ(r.status, RefineStatus::kOk) << r.message;
  EXPECT_EQ(r.num_correspondences, 200);
  EXPECT_EQ(r.num_inliers, 200);
  EXPECT_LT((r.enu_from_cam.translation - scene.enu_from_cam.translation).norm(), 1e-3);
  EXPECT_LT(RotationDifferenceDeg(r.enu_from_cam.rotation, scene.enu_from_cam.rotation), 1e-3);
  EXPECT_NEAR(r.projection.s_m, 30.0, 1e-3);
  EXPECT_NEAR(r.projection.cross_track_m, -1.2, 1e-3);  // east of a northbound route = right
  EXPECT_LT(r.rmse_px, 0.01);
}

TEST(PoseRefiner, OutliersAndConflictingVotesDoNotMoveThePose) {
  Scene scene = MakeScene(200, 50.0, 0.0, 2);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> anywhere(-20, 20);
  // 30 % of the features also matched, in another pair, a wrong point; where the wrong point
  // gets more votes the correspondence itself is wrong (an outlier for RANSAC).
  for (int i = 0; i < 60; ++i) {
    const Eigen::Vector3d wrong(anywhere(rng), 50 + 30 + anywhere(rng), 2 + 0.1 * anywhere(rng));
    for (int k = 0; k < 2; ++k) scene.pairs[k].point_matches.push_back({i, 5000 + i, wrong});
  }
  const PoseRefinement r =
      RefinePose(scene.camera, scene.keypoints, scene.pairs, 50.0, scene.route, RefineOptions());
  ASSERT_EQ(r.status, RefineStatus::kOk) << r.message;
  EXPECT_EQ(r.num_correspondences, 200);
  EXPECT_LE(r.num_inliers, 200 - 30);  // at least the 60 - 30 with more wrong votes are out
  EXPECT_LT((r.enu_from_cam.translation - scene.enu_from_cam.translation).norm(), 1e-3);
}

TEST(PoseRefiner, ThinStructureFallsBack) {
  const Scene scene = MakeScene(10, 30.0, 0.0, 3);
  const PoseRefinement r =
      RefinePose(scene.camera, scene.keypoints, scene.pairs, 30.0, scene.route, RefineOptions());
  EXPECT_EQ(r.status, RefineStatus::kThin);
  EXPECT_NE(r.message.find("10 2D-3D correspondences"), std::string::npos) << r.message;
  // Enough correspondences, but none consistent: PnP finds no pose.
  Scene noise = MakeScene(60, 30.0, 0.0, 4);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0, 1200), v(0, 370);
  for (int i = 0; i < noise.keypoints.rows(); ++i) noise.keypoints.row(i) << u(rng), v(rng), 3, 0;
  const PoseRefinement n =
      RefinePose(noise.camera, noise.keypoints, noise.pairs, 30.0, noise.route, RefineOptions());
  EXPECT_EQ(n.status, RefineStatus::kThin) << n.message;
}

TEST(PoseRefiner, APoseThatDisagreesWithTheSequenceIsRejected) {
  const Scene scene = MakeScene(200, 30.0, 0.0, 6);
  RefineOptions options;
  options.max_along_disagreement_m = 1.5;
  const PoseRefinement far =
      RefinePose(scene.camera, scene.keypoints, scene.pairs, 32.0, scene.route, options);
  EXPECT_EQ(far.status, RefineStatus::kRejected);
  EXPECT_NE(far.message.find("along the route"), std::string::npos) << far.message;
  const PoseRefinement near =
      RefinePose(scene.camera, scene.keypoints, scene.pairs, 31.4, scene.route, options);
  EXPECT_EQ(near.status, RefineStatus::kOk) << near.message;
  options.max_cross_track_m = 0.5;
  const Scene off = MakeScene(200, 30.0, 2.0, 7);
  const PoseRefinement side =
      RefinePose(off.camera, off.keypoints, off.pairs, 30.0, off.route, options);
  EXPECT_EQ(side.status, RefineStatus::kRejected);
  EXPECT_NE(side.message.find("off the route"), std::string::npos) << side.message;
}

// The local map of MakeScene's points (one database frame), each with its own random unit
// RootSIFT descriptor, and query keypoints where the map projects under each of `poses`, carrying
// those descriptors slightly changed (two poses: a pattern repeated one period off).
struct GuidedScene {
  Scene scene;
  std::vector<std::shared_ptr<const FrameMapPoints>> local_map;
  std::vector<float> query_root_sift;
};
GuidedScene MakeGuidedScene(const std::vector<Rigid3d>& keypoints_from_poses) {
  GuidedScene g;
  g.scene = MakeScene(150, 30.0, 0.0, 11);
  auto map = std::make_shared<FrameMapPoints>();
  std::mt19937 rng(12);
  std::normal_distribution<float> normal(0.f, 1.f);
  std::vector<Eigen::Vector2d> pixels;
  for (const PairResult& pair : g.scene.pairs) {
    for (const PointMatch& m : pair.point_matches) {
      if (std::find(map->point_id.begin(), map->point_id.end(), m.point_id) !=
          map->point_id.end()) {
        continue;
      }
      std::vector<float> d(128);
      float norm = 0.f;
      for (float& v : d) {
        v = std::abs(normal(rng));
        norm += v * v;
      }
      for (float& v : d) v /= std::sqrt(norm);
      map->point_id.push_back(m.point_id);
      map->point_in_enu.push_back(m.point_in_enu);
      map->root_sift.insert(map->root_sift.end(), d.begin(), d.end());
      // The query's descriptor: the map's, a little off (another view), the same in every copy.
      norm = 0.f;
      for (float& v : d) {
        v = std::abs(v + 0.01f * normal(rng));
        norm += v * v;
      }
      for (float& v : d) v /= std::sqrt(norm);
      for (const Rigid3d& pose : keypoints_from_poses) {
        const Eigen::Vector3d c = pose.Inverse() * m.point_in_enu;
        if (c.z() <= 1) continue;
        g.query_root_sift.insert(g.query_root_sift.end(), d.begin(), d.end());
        pixels.push_back(g.scene.camera.Project(c));
      }
    }
  }
  g.scene.keypoints.resize(static_cast<int>(pixels.size()), 4);
  for (size_t i = 0; i < pixels.size(); ++i) {
    g.scene.keypoints.row(static_cast<int>(i)) << static_cast<float>(pixels[i].x()),
        static_cast<float>(pixels[i].y()), 3.0f, 0.0f;
  }
  g.local_map.push_back(map);
  return g;
}

// A pose 0.5 m behind MakeScene's camera, uncertain (0.35 m along the route, as PnP on a few
// dozen matches in a turn: its points' projections are uncertain by far more than the search
// radius) or certain (centre sigma 1 mm, rotation 1e-5 rad).
PoseRefinement BehindTheCamera(const Scene& truth, bool certain) {
  PoseRefinement initial;
  initial.status = RefineStatus::kOk;
  initial.enu_from_cam = truth.enu_from_cam;
  initial.enu_from_cam.translation.y() -= 0.5;
  initial.num_inliers = 20;
  initial.sigma_along_m = initial.sigma_along_model_m = 0.35;
  initial.pose_covariance = Eigen::Matrix<double, 6, 6>::Identity() * 1e-10;
  initial.pose_covariance.bottomRightCorner<3, 3>() *= 1e4;
  if (!certain) initial.pose_covariance(4, 4) = 0.35 * 0.35;
  return initial;
}

TEST(PoseRefiner, AnUncertainPoseIsNotConfirmedByWhatLiesNearItsOwnProjections) {
  // The query sees the map's pattern exactly where the wrong pose projects it. Searching within
  // the radius around the wrong pose finds a complete, consistent set of matches for it.
  const Scene truth = MakeScene(150, 30.0, 0.0, 11);
  PoseRefinement initial = BehindTheCamera(truth, true);
  const GuidedScene g = MakeGuidedScene({initial.enu_from_cam});
  RefineOptions options;
  options.wide_search = false;
  // Certain of the initial pose: the search runs and takes the set it finds (what it did
  // whatever the initial pose's covariance).
  const PoseRefinement confident =
      RefineByProjection(g.scene.camera, g.scene.keypoints, g.query_root_sift, g.local_map, initial,
                         29.5, g.scene.route, options);
  ASSERT_EQ(confident.status, RefineStatus::kOk) << confident.message;
  EXPECT_GT(confident.num_inliers, 100);
  // Uncertain of it: the search within the radius cannot tell the pattern's period apart and the
  // initial pose is kept, with its sigma.
  initial = BehindTheCamera(truth, false);
  const PoseRefinement uncertain =
      RefineByProjection(g.scene.camera, g.scene.keypoints, g.query_root_sift, g.local_map, initial,
                         29.5, g.scene.route, options);
  EXPECT_EQ(uncertain.num_inliers, 20);
  EXPECT_EQ(uncertain.sigma_along_m, 0.35);
  EXPECT_LT((uncertain.enu_from_cam.translation - initial.enu_from_cam.translation).norm(), 1e-12);
}

TEST(PoseRefiner, TheWideSearchFindsThePoseAnUncertainOneMissed) {
  // The query sees the map where the true camera projects it; the initial pose is 0.5 m behind
  // and uncertain (the turn into the street: PnP on the few points the evaluated pairs share).
  const Scene truth = MakeScene(150, 30.0, 0.0, 11);
  const GuidedScene g = MakeGuidedScene({truth.enu_from_cam});
  const PoseRefinement initial = BehindTheCamera(truth, false);
  RefineOptions options;
  options.wide_search = false;
  const PoseRefinement narrow =
      RefineByProjection(g.scene.camera, g.scene.keypoints, g.query_root_sift, g.local_map, initial,
                         29.5, g.scene.route, options);
  EXPECT_EQ(narrow.num_inliers, 20);  // too uncertain for the search within the radius: kept
  options.wide_search = true;
  const PoseRefinement wide =
      RefineByProjection(g.scene.camera, g.scene.keypoints, g.query_root_sift, g.local_map, initial,
                         29.5, g.scene.route, options);
  ASSERT_EQ(wide.status, RefineStatus::kOk) << wide.message;
  EXPECT_GT(wide.num_inliers, 100);
  EXPECT_LT((wide.enu_from_cam.translation - truth.enu_from_cam.translation).norm(), 1e-3);
  EXPECT_NEAR(wide.projection.s_m, 30.0, 1e-3);
  EXPECT_LT(wide.sigma_along_m, 0.05);
}

TEST(PoseRefiner, TheWideSearchDoesNotChooseBetweenPeriodsOfAPattern) {
  // The map's pattern appears twice in the query, where the true camera and where the wrong,
  // uncertain pose project it: within the wide search's region both look alike, the ratio test
  // refuses them, and the initial pose is kept.
  const Scene truth = MakeScene(150, 30.0, 0.0, 11);
  const PoseRefinement initial = BehindTheCamera(truth, false);
  const GuidedScene g = MakeGuidedScene({truth.enu_from_cam, initial.enu_from_cam});
  const PoseRefinement r =
      RefineByProjection(g.scene.camera, g.scene.keypoints, g.query_root_sift, g.local_map, initial,
                         29.5, g.scene.route, RefineOptions());
  EXPECT_EQ(r.num_inliers, 20);
  EXPECT_LT((r.enu_from_cam.translation - initial.enu_from_cam.translation).norm(), 1e-12);
}

TEST(PoseRefiner, OptionsAreChecked) {
  RefineOptions options;
  options.min_correspondences = 3;
  ExpectError([&] { options.Check(); }, {"min_correspondences"});
  options = RefineOptions();
  options.max_along_disagreement_m = 0;
  ExpectError([&] { options.Check(); }, {"max_along_disagreement_m"});
  options = RefineOptions();
  options.search_sigmas = -1;
  ExpectError([&] { options.Check(); }, {"search_sigmas"});
}

}  // namespace
}  // namespace epiloc
