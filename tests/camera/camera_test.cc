#include "epiloc/camera/camera.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "camera_test_util.h"
#include "epiloc/core/error.h"
#include "test_util.h"

namespace epiloc {
namespace {

using ::testing::HasSubstr;

TEST(Camera, UnprojectThenProjectIsIdentityOverTheImage) {
  const Camera camera = KittiCamera();
  double worst_px = 0.0;
  for (double v = 0.0; v <= camera.height - 1; v += (camera.height - 1) / 16.0) {
    for (double u = 0.0; u <= camera.width - 1; u += (camera.width - 1) / 32.0) {
      const Eigen::Vector2d pixel(u, v);
      const Eigen::Vector2d ray = camera.Unproject(pixel);
      for (const double depth : {0.5, 7.0, 80.0}) {
        const Eigen::Vector3d point = depth * Eigen::Vector3d(ray.x(), ray.y(), 1.0);
        worst_px = std::max(worst_px, (camera.Project(point) - pixel).norm());
      }
    }
  }
  EXPECT_LT(worst_px, 1e-6);
}

TEST(Camera, ProjectThenUnprojectRecoversTheRay) {
  const Camera camera = KittiCamera();
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, camera.width - 1.0);
  std::uniform_real_distribution<double> v(0.0, camera.height - 1.0);
  std::uniform_real_distribution<double> depth(1.0, 100.0);
  for (int i = 0; i < 200; ++i) {
    // A point that lands inside the image.
    const Eigen::Vector2d ray = camera.Unproject({u(rng), v(rng)});
    const double z = depth(rng);
    const Eigen::Vector3d point(z * ray.x(), z * ray.y(), z);
    const Eigen::Vector2d back = camera.Unproject(camera.Project(point));
    EXPECT_LT((back - point.head<2>() / z).norm(), 1e-9);
  }
}

TEST(Camera, DistortionModelMatchesOpenCvFormula) {
  const Camera camera = KittiCamera();
  const double x = 0.3, y = -0.2;
  const double r2 = x * x + y * y;
  const double radial = 1 - 0.37 * r2 + 0.2 * r2 * r2 - 0.07 * r2 * r2 * r2;
  const Eigen::Vector2d expected(x * radial + 2 * 0.002 * x * y + 0.001 * (r2 + 2 * x * x),
                                 y * radial + 0.002 * (r2 + 2 * y * y) + 2 * 0.001 * x * y);
  EXPECT_LT((camera.Distort({x, y}) - expected).norm(), 1e-15);
  EXPECT_LT((camera.Undistort(expected) - Eigen::Vector2d(x, y)).norm(), 1e-12);
  // The principal point is the image of the optical axis.
  EXPECT_LT((camera.Project({0, 0, 5}) - Eigen::Vector2d(690.0, 233.2)).norm(), 1e-12);
}

TEST(Camera, PinholeWithoutDistortion) {
  Camera camera = KittiCamera();
  camera.distortion.fill(0.0);
  EXPECT_FALSE(camera.HasDistortion());
  EXPECT_TRUE(KittiCamera().HasDistortion());
  const Eigen::Vector2d pixel = camera.Project({1.0, -0.5, 10.0});
  EXPECT_NEAR(pixel.x(), 690.0 + 98.4, 1e-12);
  EXPECT_NEAR(pixel.y(), 233.2 - 49.05, 1e-12);
  EXPECT_LT((camera.Unproject(pixel) - Eigen::Vector2d(0.1, -0.05)).norm(), 1e-15);
  Eigen::Matrix3d k;
  k << 984.0, 0.0, 690.0, 0.0, 981.0, 233.2, 0.0, 0.0, 1.0;
  EXPECT_EQ(camera.K(), k);
}

TEST(Camera, CheckReportsInvalidValues) {
  EXPECT_NO_THROW(KittiCamera().Check("calib_cam_to_cam.txt"));
  Camera camera = KittiCamera();
  camera.cx = 1500.0;
  EXPECT_THAT(ErrorOf([&] { camera.Check("calib_cam_to_cam.txt"); }),
              HasSubstr("calib_cam_to_cam.txt: principal point (1500, 233.2) "
                        "lies outside the 1392x512 image"));
  camera = KittiCamera();
  camera.cy = -3.0;
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("outside"));
  camera = KittiCamera();
  camera.fx = -984.0;
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("c: focal lengths fx=-984"));
  camera = KittiCamera();
  camera.fy = 0.0;
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("must be positive"));
  camera = KittiCamera();
  camera.fx = std::numeric_limits<double>::infinity();
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("focal"));
  camera = KittiCamera();
  camera.width = 0;
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("image size 0x512"));
  camera = KittiCamera();
  camera.cx = std::nan("");
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("principal point is not finite"));
  camera = KittiCamera();
  camera.distortion[4] = std::nan("");
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("distortion"));
}

TEST(Camera, ScaledKeepsPixelCentres) {
  const Camera camera = KittiCamera();
  const Camera half = camera.Scaled(0.5);
  EXPECT_EQ(half.width, 696);
  EXPECT_EQ(half.height, 256);
  EXPECT_DOUBLE_EQ(half.fx, 492.0);
  EXPECT_DOUBLE_EQ(half.fy, 490.5);
  EXPECT_DOUBLE_EQ(half.cx, 344.75);  // (690 + 0.5) * 0.5 - 0.5
  EXPECT_DOUBLE_EQ(half.cy, 116.35);
  EXPECT_EQ(half.distortion,
            camera.distortion);  // acts on normalised coordinates
  EXPECT_NO_THROW(half.Check("half"));

  // A point's pixel in the scaled image is its pixel in the original, with the
  // image's edges (at -0.5 and width - 0.5) mapped onto each other.
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> xy(-3.0, 3.0);
  for (const double factor : {0.5, 0.25, 2.0, 1.0 / 3.0}) {
    const Camera scaled = camera.Scaled(factor);
    for (int i = 0; i < 20; ++i) {
      const Eigen::Vector3d point(xy(rng), 0.3 * xy(rng), 10.0);
      const Eigen::Vector2d original = camera.Project(point);
      const Eigen::Vector2d expected = (original.array() + 0.5) * factor - 0.5;
      EXPECT_LT((scaled.Project(point) - expected).norm(), 1e-9);
    }
  }
  const Camera back = camera.Scaled(2.0).Scaled(0.5);
  EXPECT_EQ(back.width, camera.width);
  EXPECT_EQ(back.height, camera.height);
  EXPECT_NEAR(back.cx, camera.cx, 1e-12);
  EXPECT_NEAR(back.fy, camera.fy, 1e-12);
}

TEST(Camera, Equality) {
  Camera a = KittiCamera();
  Camera b = KittiCamera();
  EXPECT_TRUE(a == b);
  b.distortion[2] = 0.0;
  EXPECT_FALSE(a == b);
  b = a;
  b.height = 513;
  EXPECT_FALSE(a == b);
}

}  // namespace
}  // namespace epiloc
