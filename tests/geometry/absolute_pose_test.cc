#include "epiloc/geometry/absolute_pose.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "test_util.h"

namespace epiloc {
namespace {

Camera TestCamera() {
  Camera camera;
  camera.width = 1242;
  camera.height = 375;
  camera.fx = camera.fy = 721.5;
  camera.cx = 609.6;
  camera.cy = 172.9;
  return camera;
}

// A camera 2 km from the world origin (map coordinates are large), looking roughly north-east.
Rigid3d TestPose() {
  const Eigen::Matrix3d r =
      (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(-0.01, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  const Rigid3d world_from_cam = Rigid3d::FromMatrix(r, Eigen::Vector3d(1500.0, 1300.0, 1.6));
  return world_from_cam.Inverse();
}

struct Correspondences {
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
};

// `n` points 3-60 m in front of the camera, seen in the image; pixels with Gaussian noise of
// `noise_px`; a fraction `outliers` of the pixels replaced by random ones.
Correspondences MakeCorrespondences(int n, double noise_px, double outliers, uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Camera camera = TestCamera();
  const Rigid3d cam_from_world = TestPose();
  const Rigid3d world_from_cam = cam_from_world.Inverse();
  std::uniform_real_distribution<double> u(0, camera.width - 1), v(0, camera.height - 1);
  std::uniform_real_distribution<double> depth(3.0, 60.0), unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  Correspondences c;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d pixel(u(rng), v(rng));
    const double z = depth(rng);
    const Eigen::Vector3d x_cam((pixel.x() - camera.cx) / camera.fx * z,
                                (pixel.y() - camera.cy) / camera.fy * z, z);
    c.points.push_back(world_from_cam * x_cam);
    if (unit(rng) < outliers) {
      c.pixels.emplace_back(u(rng), v(rng));
    } else {
      c.pixels.push_back(pixel + Eigen::Vector2d(noise(rng), noise(rng)));
    }
  }
  return c;
}

TEST(AbsolutePose, RecoversTheExactPoseFromNoiseFreeCorrespondences) {
  const Correspondences c = MakeCorrespondences(60, 0.0, 0.0, 1);
  const PnpResult result = EstimateAbsolutePose(c.pixels, c.points, TestCamera());
  ASSERT_TRUE(result.success) << result.message;
  EXPECT_EQ(result.num_inliers, 60);
  EXPECT_LT(result.rmse_px, 1e-6);
  const Rigid3d truth = TestPose();
  EXPECT_LT((result.cam_from_world.Inverse().translation - truth.Inverse().translation).norm(),
            1e-6);
  EXPECT_LT(RotationDifferenceDeg(result.cam_from_world.rotation, truth.rotation), 1e-6);
}

TEST(AbsolutePose, IsRobustToNoiseAndOutliers) {
  const Correspondences c = MakeCorrespondences(300, 0.5, 0.4, 2);
  const PnpResult result = EstimateAbsolutePose(c.pixels, c.points, TestCamera());
  ASSERT_TRUE(result.success) << result.message;
  // About 180 true correspondences; a few outliers fall within the threshold by chance.
  EXPECT_GT(result.num_inliers, 160);
  EXPECT_LT(result.num_inliers, 200);
  EXPECT_LT(result.rmse_px, 1.0);
  const Rigid3d truth = TestPose();
  EXPECT_LT((result.cam_from_world.Inverse().translation - truth.Inverse().translation).norm(),
            0.03);
  EXPECT_LT(RotationDifferenceDeg(result.cam_from_world.rotation, truth.rotation), 0.05);
  // Inliers are (mostly) the true correspondences.
  int flagged = 0;
  for (const char inlier : result.inlier_mask) flagged += inlier;
  EXPECT_EQ(flagged, result.num_inliers);
}

// The Jacobian against central differences of the projection under the perturbation it
// documents: rotation exp([dθ]x) R on the left, camera centre C + dC, x_cam = R (X - C).
TEST(AbsolutePose, ProjectionPoseJacobianMatchesNumericalDifferences) {
  const Camera camera = TestCamera();
  const Rigid3d cam_from_world = TestPose();
  const Eigen::Matrix3d r = cam_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d centre = cam_from_world.Inverse().translation;
  const Eigen::Vector3d point = cam_from_world.Inverse() * Eigen::Vector3d(-3.0, 1.2, 14.0);
  const auto project = [&](const Eigen::Matrix<double, 6, 1>& delta) {
    const Eigen::Vector3d dtheta = delta.head<3>();
    const Eigen::Matrix3d rotated =
        (dtheta.norm() > 0
             ? Eigen::AngleAxisd(dtheta.norm(), dtheta.normalized()).toRotationMatrix()
             : Eigen::Matrix3d::Identity()) *
        r;
    return camera.Project(rotated * (point - (centre + delta.tail<3>())));
  };
  const Eigen::Matrix<double, 2, 6> j = ProjectionPoseJacobian(camera, r * (point - centre), r);
  const double h = 1e-6;
  for (int k = 0; k < 6; ++k) {
    Eigen::Matrix<double, 6, 1> delta = Eigen::Matrix<double, 6, 1>::Zero();
    delta(k) = h;
    const Eigen::Vector2d numeric = (project(delta) - project(-delta)) / (2 * h);
    EXPECT_NEAR(j(0, k), numeric.x(), 1e-3 * (1 + std::abs(numeric.x()))) << "column " << k;
    EXPECT_NEAR(j(1, k), numeric.y(), 1e-3 * (1 + std::abs(numeric.y()))) << "column " << k;
  }
}

// The grouped jackknife over bands of image columns against the model covariance (independent
// pixel errors): about the same when the errors are independent; much larger when a region of
// the image shares one error (a part of the map off by a common error), which the model cannot
// see and which moves the pose by far more than the model's sigma.
TEST(AbsolutePose, JackknifeAgreesWithTheModelForIndependentErrors) {
  const Correspondences c = MakeCorrespondences(300, 0.7, 0.0, 5);
  const PnpResult result = EstimateAbsolutePose(c.pixels, c.points, TestCamera());
  ASSERT_TRUE(result.success) << result.message;
  EXPECT_EQ(result.jackknife_groups, 6);
  const double ratio =
      result.center_covariance_jackknife.trace() / result.center_covariance.trace();
  EXPECT_GT(ratio, 0.2);
  EXPECT_LT(ratio, 5.0);
}

TEST(AbsolutePose, JackknifeSeesAnErrorSharedByARegionOfTheImage) {
  Correspondences c = MakeCorrespondences(300, 0.2, 0.0, 6);
  const Camera camera = TestCamera();
  for (Eigen::Vector2d& pixel : c.pixels) {
    if (pixel.x() < camera.width / 6.0) pixel += Eigen::Vector2d(1.5, 0.0);
  }
  const PnpResult result = EstimateAbsolutePose(c.pixels, c.points, camera);
  ASSERT_TRUE(result.success) << result.message;
  EXPECT_EQ(result.num_inliers, 300);  // the shared error stays within the inlier threshold
  const Eigen::Vector3d error =
      result.cam_from_world.Inverse().translation - TestPose().Inverse().translation;
  const double model = std::sqrt(result.center_covariance.trace());
  const double jackknife = std::sqrt(result.center_covariance_jackknife.trace());
  EXPECT_GT(error.norm(), 3.0 * model);  // the model's sigma is not honest here ...
  EXPECT_LT(error.norm(), 3.0 * jackknife);  // ... the jackknife's is
}

TEST(AbsolutePose, JackknifeNeedsEnoughInliersPerBand) {
  const Correspondences c = MakeCorrespondences(20, 0.5, 0.0, 7);
  const PnpResult result = EstimateAbsolutePose(c.pixels, c.points, TestCamera());
  ASSERT_TRUE(result.success) << result.message;
  EXPECT_EQ(result.jackknife_groups, 0);  // 20 inliers: 2 bands of 8, fewer than 3
  EXPECT_EQ(result.center_covariance_jackknife.trace(), 0.0);
  PnpOptions off;
  off.jackknife_groups = 0;
  const Correspondences many = MakeCorrespondences(200, 0.5, 0.0, 8);
  EXPECT_EQ(EstimateAbsolutePose(many.pixels, many.points, TestCamera(), off).jackknife_groups, 0);
}

TEST(AbsolutePose, FailsAsAValueWithTooFewCorrespondences) {
  const Correspondences c = MakeCorrespondences(8, 0.0, 0.0, 3);
  const PnpResult result = EstimateAbsolutePose(c.pixels, c.points, TestCamera());
  EXPECT_FALSE(result.success);
  EXPECT_THAT(result.message, ::testing::HasSubstr("8 correspondences"));
}

TEST(AbsolutePose, FailsAsAValueWhenAllAreOutliers) {
  const Correspondences c = MakeCorrespondences(40, 0.0, 1.0, 4);
  const PnpResult result = EstimateAbsolutePose(c.pixels, c.points, TestCamera());
  EXPECT_FALSE(result.success);
  EXPECT_FALSE(result.message.empty());
}

TEST(AbsolutePose, RejectsMismatchedInputsAndOptions) {
  ExpectError([] { EstimateAbsolutePose({Eigen::Vector2d(0, 0)}, {}, TestCamera()); },
              {"1 pixels but 0 points"});
  PnpOptions options;
  options.max_reprojection_px = 0;
  ExpectError([&] { options.Check(); }, {"max_reprojection_px"});
}

}  // namespace
}  // namespace epiloc
