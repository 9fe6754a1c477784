// Bundle adjustment on exact synthetic data: cameras along a curve looking at random points,
// poses and points perturbed, the monocular gauge held by one fixed pose and one translation
// coordinate of a second (BundleProblem::scale_pose); the adjustment must return to the truth.
#include "epiloc/vo/bundle_adjustment.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "test_util.h"

namespace epiloc {
namespace {

Eigen::Vector3d Centre(const Rigid3d& cam_from_world) {
  return -(cam_from_world.rotation.conjugate() * cam_from_world.translation);
}

struct Scene {
  std::vector<Rigid3d> truth;
  BundleProblem problem;
};

// Eight cameras 1 m apart turning 20 degrees in all, 300 points 13-40 m ahead, every point seen
// by every camera; the problem starts from perturbed poses (except the first) and points.
Scene MakeScene(std::mt19937_64& rng) {
  Scene scene;
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int i = 0; i < 8; ++i) {
    const double yaw = 0.05 * i;
    const Eigen::Quaterniond world_from_cam(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()));
    const Eigen::Vector3d centre(0.3 * std::sin(yaw) * i, 0.0, 1.0 * i);
    const Rigid3d cam_from_world(world_from_cam.conjugate(),
                                 -(world_from_cam.conjugate() * centre));
    scene.truth.push_back(cam_from_world);
  }
  std::vector<Eigen::Vector3d> points;
  for (int p = 0; p < 300; ++p) {
    points.emplace_back(8.0 * uniform(rng), 3.0 * uniform(rng), 30.0 + 10.0 * uniform(rng));
  }
  BundleProblem& problem = scene.problem;
  for (size_t i = 0; i < scene.truth.size(); ++i) {
    Rigid3d pose = scene.truth[i];
    if (i > 0) {
      pose.rotation = pose.rotation *
                      Eigen::Quaterniond(Eigen::AngleAxisd(
                          0.01, Eigen::Vector3d(noise(rng), noise(rng), noise(rng)).normalized()));
      pose.translation += 0.05 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    }
    problem.cam_from_world.push_back(pose);
    problem.pose_fixed.push_back(i == 0);
  }
  for (size_t p = 0; p < points.size(); ++p) {
    problem.points_in_world.push_back(points[p] +
                                      0.2 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    for (size_t i = 0; i < scene.truth.size(); ++i) {
      const Eigen::Vector3d x = scene.truth[i] * points[p];
      problem.observations.push_back({static_cast<int>(i), static_cast<int>(p),
                                      Eigen::Vector2d(x.x() / x.z(), x.y() / x.z())});
    }
  }
  return scene;
}

TEST(BundleAdjustment, ScaleGaugeRecoversExactPoses) {
  std::mt19937_64 rng(7);
  Scene scene = MakeScene(rng);
  BundleProblem& problem = scene.problem;
  // The second camera's largest translation coordinate holds the scale at its true value.
  problem.scale_pose = 1;
  scene.truth[1].translation.cwiseAbs().maxCoeff(&problem.scale_axis);
  problem.cam_from_world[1].translation[problem.scale_axis] =
      scene.truth[1].translation[problem.scale_axis];
  BundleOptions options;
  options.focal_px = 700.0;
  options.max_iterations = 50;
  const BundleSummary summary = SolveBundle(problem, options);
  EXPECT_TRUE(summary.solved);
  EXPECT_GT(summary.initial_rms_px, 1.0);
  EXPECT_LT(summary.final_rms_px, 1e-3);
  for (size_t i = 0; i < scene.truth.size(); ++i) {
    EXPECT_LT((Centre(problem.cam_from_world[i]) - Centre(scene.truth[i])).norm(), 1e-4) << i;
    EXPECT_LT(problem.cam_from_world[i].rotation.angularDistance(scene.truth[i].rotation), 1e-6)
        << i;
  }
}

TEST(BundleAdjustment, ScaleGaugeIsChecked) {
  std::mt19937_64 rng(8);
  Scene scene = MakeScene(rng);
  scene.problem.scale_pose = 8;  // out of range
  ExpectError([&] { SolveBundle(scene.problem, BundleOptions()); }, {"scale gauge pose 8"});
}

}  // namespace
}  // namespace epiloc
