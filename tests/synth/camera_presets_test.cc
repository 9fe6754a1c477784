#include "epiloc/synth/camera_presets.h"

#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/synth/trajectory.h"

namespace epiloc {
namespace {

TEST(CameraPresets, DashcamAndVgaHaveTheirSizeRateAndFieldOfView) {
  DriveOptions drive = DriveOptions::Query();
  ApplyQueryCameraPreset("dashcam1080", &drive);
  EXPECT_EQ(drive.camera.width, 1920);
  EXPECT_EQ(drive.camera.height, 1080);
  EXPECT_EQ(drive.frame_rate_hz, 30.0);
  EXPECT_NEAR(HorizontalFovDeg(drive.camera), 120.0, 1e-6);
  EXPECT_TRUE(drive.camera.HasDistortion());
  EXPECT_NO_THROW(CheckDistortionInvertible(drive.camera, "dashcam"));
  ApplyQueryCameraPreset("vga", &drive);
  EXPECT_EQ(drive.camera.width, 640);
  EXPECT_EQ(drive.camera.height, 480);
  EXPECT_NEAR(HorizontalFovDeg(drive.camera), 60.0, 1e-6);
  ApplyQueryCameraPreset("default", &drive);
  EXPECT_EQ(drive.camera, DriveOptions::Query().camera);
  EXPECT_THROW(ApplyQueryCameraPreset("fisheye", &drive), Error);
}

// The synthetic world's cameras pass the calibration checks every drive.json goes through.
TEST(CameraPresets, EveryPresetAndTheSurveyCameraPassCameraCheck) {
  EXPECT_NO_THROW(DriveOptions::Survey().camera.Check("survey"));
  for (const std::string& name : QueryCameraPresets()) {
    DriveOptions drive = DriveOptions::Query();
    ApplyQueryCameraPreset(name, &drive);
    EXPECT_NO_THROW(drive.camera.Check(name)) << name;
  }
}

TEST(CameraPresets, FieldOfViewAndSize) {
  Camera pinhole = DriveOptions::Survey().camera;  // 800 px wide, fx 600
  EXPECT_NEAR(HorizontalFovDeg(pinhole), 2 * std::atan(400.0 / 600.0) * 180 / M_PI, 1e-9);
  const Camera wide = WithHorizontalFovDeg(pinhole, 100.0);
  EXPECT_NEAR(wide.fx, 400.0 / std::tan(50.0 * M_PI / 180), 1e-6);
  EXPECT_EQ(wide.fx, wide.fy);
  const Camera small = WithSize(pinhole, 400, 300);
  EXPECT_EQ(small.width, 400);
  EXPECT_EQ(small.height, 300);
  EXPECT_EQ(small.cx, 199.5);
  EXPECT_EQ(small.cy, 149.5);
  EXPECT_NEAR(HorizontalFovDeg(small), HorizontalFovDeg(pinhole), 1e-9);
  // Barrel distortion: the focal length that gives 90 deg is longer than a pinhole's.
  Camera barrel = pinhole;
  barrel.distortion = {-0.3, 0.08, 0, 0, 0};
  const Camera barrel_90 = WithHorizontalFovDeg(barrel, 90.0);
  EXPECT_NEAR(HorizontalFovDeg(barrel_90), 90.0, 1e-6);
  EXPECT_GT(barrel_90.fx, 400.0);
  EXPECT_NO_THROW(CheckDistortionInvertible(barrel_90, "barrel"));
  // Distortion that folds over inside the image is refused.
  Camera folding = pinhole;
  folding.fx = folding.fy = 300;
  folding.distortion = {-0.5, 0.0, 0, 0, 0};
  EXPECT_THROW(CheckDistortionInvertible(folding, "folding"), Error);
  EXPECT_THROW(WithHorizontalFovDeg(folding, 170.0), Error);
  EXPECT_THROW(WithHorizontalFovDeg(pinhole, 180.0), Error);
}

}  // namespace
}  // namespace epiloc
