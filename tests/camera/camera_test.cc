#include "epiloc/camera/camera.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

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

// Issue 18 (leftovers): absurd distortion and fy / fx were accepted as long as each coefficient
// stayed below its bound.
TEST(Camera, CheckRefusesADistortionThatFoldsOverAndNonSquarePixels) {
  Camera camera = KittiCamera();
  camera.distortion = {50.0, -300.0, 0.0, 0.0, 0.0};
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }),
              HasSubstr("c: distortion k1=50 k2=-300 k3=0 is not invertible over the image: the "
                        "distorted radius stops growing"));
  camera.distortion = {-2.0, 0.0, 0.0, 0.0, 0.0};  // folds at r = 0.41, the corner is at 0.77
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("not invertible over the image"));
  camera.distortion = {0.0, 0.0, 0.0, 0.0, -30.0};
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("not invertible over the image"));
  camera.distortion = {50.0, 0.0, 0.0, 0.0, 0.0};  // one-to-one, but stretched 30 times
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("stretches the image"));
  camera = KittiCamera();
  camera.fy = 20.0 * camera.fx;  // within the focal length's own bounds for this image size
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("c: fy / fx = 20 "));
  camera.fy = 0.4 * camera.fx;
  EXPECT_THAT(ErrorOf([&] { camera.Check("c"); }), HasSubstr("fy / fx = 0.4"));
  camera.fy = 1.9 * camera.fx;  // generous: real sensors stay near 1
  EXPECT_NO_THROW(camera.Check("c"));
}

TEST(Camera, CheckAcceptsRealCalibrations) {
  EXPECT_NO_THROW(KittiCamera().Check("kitti"));
  // OpenCV-typical wide-angle values at 1080p.
  Camera wide;
  wide.width = 1920;
  wide.height = 1080;
  wide.fx = wide.fy = 1000.0;
  wide.cx = 959.5;
  wide.cy = 539.5;
  wide.distortion = {-0.4, 0.2, 0.0, 0.0, -0.05};
  EXPECT_NO_THROW(wide.Check("wide"));
  wide.distortion = {-0.4, 0.2, 0.001, -0.001, -0.05};
  EXPECT_NO_THROW(wide.Check("wide"));
  wide.distortion = {0.05, -0.01, 0.0, 0.0, 0.0};  // mild pincushion
  EXPECT_NO_THROW(wide.Check("wide"));
  // The unrectified cameras of the shared KITTI drive (K_0N, D_0N of calib_cam_to_cam.txt).
  const std::string calib = (KittiRawDrive().parent_path() / "calib_cam_to_cam.txt").string();
  std::ifstream in(calib);
  if (!in) GTEST_SKIP() << calib << " is absent";
  std::map<std::string, std::vector<double>> values;
  for (std::string line; std::getline(in, line);) {
    std::istringstream fields(line);
    std::string key;
    fields >> key;
    for (double v; fields >> v;) values[key].push_back(v);
  }
  for (int n = 0; n < 4; ++n) {
    SCOPED_TRACE(n);
    const std::vector<double>& k = values[fmt::format("K_0{}:", n)];
    const std::vector<double>& d = values[fmt::format("D_0{}:", n)];
    const std::vector<double>& size = values[fmt::format("S_0{}:", n)];
    ASSERT_EQ(k.size(), 9u);
    ASSERT_EQ(d.size(), 5u);
    ASSERT_EQ(size.size(), 2u);
    Camera camera;
    camera.width = static_cast<int>(size[0]);
    camera.height = static_cast<int>(size[1]);
    camera.fx = k[0];
    camera.cx = k[2];
    camera.fy = k[4];
    camera.cy = k[5];
    for (int i = 0; i < 5; ++i) camera.distortion[i] = d[i];
    EXPECT_NO_THROW(camera.Check(calib));
  }
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
