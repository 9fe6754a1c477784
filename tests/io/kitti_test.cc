#include "epiloc/io/kitti.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "epiloc/geo/rigid3.h"
#include "io_test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

const std::string kRawDrive =
    std::string(EPILOC_SHARED_DATA_DIR) + "/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync";

// A tiny KITTI tree with identity calibration (IMU = velodyne = camera 0 axes), 40x30 images,
// camera 1 0.5 m along +x, and OXTS records heading north (yaw 90 deg).
class MiniKitti {
 public:
  explicit MiniKitti(int frames = 4) {
    const std::string identity = "1 0 0 0 1 0 0 0 1";
    WriteText(root_ / "calib_cam_to_cam.txt",
              "calib_time: 09-Jan-2012 13:57:47\nR_rect_00: " + identity +
                  "\nS_rect_00: 40 30\nP_rect_00: 40 0 19.5 0 0 40 14.5 0 0 0 1 0\n"
                  "S_rect_01: 40 30\nP_rect_01: 40 0 19.5 -20 0 40 14.5 0 0 0 1 0\n");
    WriteText(root_ / "calib_velo_to_cam.txt", "R: " + identity + "\nT: 0 0 0\n");
    WriteText(root_ / "calib_imu_to_velo.txt", "R: " + identity + "\nT: 0 0 0\n");
    std::string times, oxts_times;
    for (int i = 0; i < frames; ++i) {
      for (const char* camera : {"image_00", "image_01"}) {
        WriteImage(fmt::format("{}/{}/data/{:010d}.png", drive(), camera, i),
                   Pattern(40, 30, CV_8UC1, i));
      }
      std::string values = fmt::format("{} 8.4 100 0 0 {}", 49.0 + i * 1e-5, M_PI / 2);
      for (int k = 6; k < 30; ++k) values += " 0";
      WriteText(fmt::format("{}/oxts/data/{:010d}.txt", drive(), i), values);
      times += fmt::format("2011-09-26 13:04:32.{:09d}\n", 100000000 * i + 5000000);
      oxts_times += fmt::format("2011-09-26 13:04:32.{:09d}\n", 100000000 * i);
    }
    WriteText(drive() + "/image_00/timestamps.txt", times);
    WriteText(drive() + "/image_01/timestamps.txt", times);
    WriteText(drive() + "/oxts/timestamps.txt", oxts_times);
  }

  std::string root() const { return root_.str(); }
  std::string drive() const { return root_ / "2011_09_26_drive_0001_sync"; }
  KittiImportOptions Options(int camera = 0) const {
    KittiImportOptions options;
    options.raw_drive_dir = drive();
    options.camera = camera;
    return options;
  }

 private:
  TempDir root_;
};

Eigen::Vector3d Enu(const EnuFrame& frame, const PositionSample& s) {
  return frame.ToEnu(s.position);
}

TEST(KittiImport, ChainsTheCalibrationOnSyntheticData) {
  MiniKitti kitti;
  const Drive cam0 = ImportKitti(kitti.Options(0));
  const Drive cam1 = ImportKitti(kitti.Options(1));
  EXPECT_EQ(cam0.name, "kitti_2011_09_26_0001_cam0");
  ASSERT_EQ(cam0.frames.size(), 4u);
  EXPECT_TRUE(fs::path(cam0.frames[0].image).is_absolute());
  EXPECT_EQ(cam1.camera.fx, 40.0);
  EXPECT_FALSE(cam1.camera.HasDistortion());
  ASSERT_TRUE(cam0.ground_truth.has_value());
  ASSERT_EQ(cam1.ground_truth->samples.size(), 4u);
  const PositionSample& a = cam0.ground_truth->samples[2];
  const PositionSample& b = cam1.ground_truth->samples[2];
  EXPECT_EQ(b.frame, 2);
  // Camera 0 sits on the OXTS unit; camera 1 0.5 m along IMU x, which points north (yaw 90 deg).
  const EnuFrame frame(a.position);
  EXPECT_NEAR(a.position.lat_deg, 49.00002, 1e-12);
  EXPECT_LT((Enu(frame, b) - Eigen::Vector3d(0, 0.5, 0)).norm(), 1e-6);
  const Eigen::Quaterniond expected(EnuFromImu(0, 0, M_PI / 2));
  EXPECT_LT(RotationDifferenceDeg(*a.enu_from_cam, expected), 1e-6);
  // Without noise, GNSS = ground-truth positions without orientation.
  ASSERT_EQ(cam0.gnss.samples.size(), 4u);
  EXPECT_TRUE(cam0.gnss.samples[1].position.lat_deg ==
              cam0.ground_truth->samples[1].position.lat_deg);
  EXPECT_FALSE(cam0.gnss.samples[1].enu_from_cam.has_value());
  EXPECT_TRUE(cam0.lidar.empty());  // no velodyne_points folder
}

TEST(KittiImport, SelectsFramesByStartStopStep) {
  MiniKitti kitti(10);
  KittiImportOptions options = kitti.Options();
  options.start = 2;
  options.stop = 9;
  options.step = 3;
  const Drive drive = ImportKitti(options);
  ASSERT_EQ(drive.frames.size(), 3u);
  EXPECT_EQ(drive.frames[0].frame, 2);
  EXPECT_EQ(drive.frames[2].frame, 8);
  EXPECT_EQ(drive.ground_truth->samples.size(), 7u);  // the whole span 2..8
  EXPECT_EQ(drive.ground_truth->samples.front().frame, 2);
}

TEST(KittiImport, RejectsBadInput) {
  MiniKitti kitti;
  KittiImportOptions options = kitti.Options();
  options.camera = 4;
  ExpectError([&] { ImportKitti(options); }, {"camera 4"});
  options.camera = 2;
  ExpectError([&] { ImportKitti(options); }, {"P_rect_02", "calib_cam_to_cam.txt"});
  options.camera = 0;
  options.start = 20;
  ExpectError([&] { ImportKitti(options); }, {"image_00/data", "no frames"});
  options.start = 0;
  options.step = 0;
  ExpectError([&] { ImportKitti(options); }, {"step"});
  options.step = 1;
  // Issue 18 (unseen inputs): 1e308 wrote empty latitudes and an infinite altitude, exit 0.
  options.gps_noise_sigma_m = 1e308;
  ExpectError([&] { ImportKitti(options); }, {"gps_noise_sigma_m", "[0, 1000]"});
  options.gps_noise_sigma_m = 0;
  fs::remove(kitti.root() + "/calib_imu_to_velo.txt");
  ExpectError([&] { ImportKitti(options); }, {kitti.root() + "/calib_imu_to_velo.txt"});
  WriteText(kitti.root() + "/calib_imu_to_velo.txt", "R: 1 0 0 0 1 0 0 0 1\n");
  ExpectError([&] { ImportKitti(options); }, {"calib_imu_to_velo.txt", "missing key 'T'"});
  WriteText(kitti.root() + "/calib_imu_to_velo.txt", "R: 1 0 0 0 1 0 0 0 1\nT: 0 0\n");
  ExpectError([&] { ImportKitti(options); }, {"calib_imu_to_velo.txt", "'T' has 2 values"});
  options.raw_drive_dir = kitti.root() + "/nothing_here";
  ExpectError([&] { ImportKitti(options); }, {"nothing_here"});
}

// The real KITTI drive 0005: camera 0 and 1 tracks, GNSS simulation and LiDAR poses.
class KittiRealData : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::is_directory(kRawDrive)) {
      GTEST_SKIP() << "KITTI raw drive not found at " << kRawDrive << "; skipping real-data test";
    }
  }

  static double RouteLength(const PositionTrack& track) {
    const EnuFrame frame(track.samples.front().position);
    double length = 0;
    for (size_t i = 1; i < track.samples.size(); ++i) {
      length += (Enu(frame, track.samples[i]) - Enu(frame, track.samples[i - 1])).norm();
    }
    return length;
  }
};

TEST_F(KittiRealData, ImportsCameraZeroAndOne) {
  TempDir out;
  KittiImportOptions options;
  options.raw_drive_dir = kRawDrive;
  options.out_dir = out / "cam0";
  const Drive imported = ImportKitti(options);
  const Drive cam0 = LoadDrive(out / "cam0");
  EXPECT_EQ(cam0.name, "kitti_2011_09_26_0005_cam0");
  ASSERT_EQ(cam0.frames.size(), 154u);
  EXPECT_EQ(cam0.frames.front().frame, 0);
  EXPECT_EQ(cam0.frames.back().frame, 153);
  EXPECT_NEAR(cam0.frames[0].timestamp_s, 1317042272.351950336, 1e-6);
  EXPECT_EQ(cam0.camera.width, 1242);
  EXPECT_EQ(cam0.camera.height, 375);
  EXPECT_EQ(cam0.camera.fx, 721.5377);
  EXPECT_EQ(cam0.frames, imported.frames);
  EXPECT_EQ(cam0.ground_truth->samples, imported.ground_truth->samples);
  EXPECT_EQ(cam0.lidar, imported.lidar);
  EXPECT_TRUE(PositionFrames(cam0, cam0.gnss).missing.empty());

  options.camera = 1;
  options.out_dir = out / "cam1";
  ImportKitti(options);
  const Drive cam1 = LoadDrive(out / "cam1");
  ASSERT_EQ(cam1.frames.size(), 154u);

  const PositionTrack& truth0 = *cam0.ground_truth;
  const PositionTrack& truth1 = *cam1.ground_truth;
  ASSERT_EQ(truth0.samples.size(), 154u);
  ASSERT_EQ(truth1.samples.size(), 154u);
  const double length = RouteLength(truth0);
  EXPECT_GT(length, 60.0);
  EXPECT_LT(length, 75.0);

  double max_offset_error = 0, offset_sum = 0;
  std::vector<double> axis_angles;
  const EnuFrame frame(truth0.samples.front().position);
  for (size_t i = 0; i < truth0.samples.size(); ++i) {
    const PositionSample& a = truth0.samples[i];
    const PositionSample& b = truth1.samples[i];
    ASSERT_EQ(a.frame, b.frame);
    const Eigen::Vector3d offset = Enu(frame, b) - Enu(frame, a);
    offset_sum += offset.norm();
    max_offset_error = std::max(max_offset_error, std::abs(offset.norm() - 0.54));
    EXPECT_GT(offset.dot(*a.enu_from_cam * Eigen::Vector3d::UnitX()), 0.5) << "frame " << a.frame;
    // The optical axis points along the travel direction, taken over +-5 samples (~4 m) as OXTS
    // positions jitter by decimetres.
    if (i < 5 || i + 5 >= truth0.samples.size()) continue;
    const Eigen::Vector3d travel =
        Enu(frame, truth0.samples[i + 5]) - Enu(frame, truth0.samples[i - 5]);
    if (travel.norm() < 1.0) continue;
    const Eigen::Vector3d axis = *a.enu_from_cam * Eigen::Vector3d::UnitZ();
    axis_angles.push_back(std::acos(std::min(1.0, axis.dot(travel.normalized()))) * 180 / M_PI);
  }
  EXPECT_LT(max_offset_error, 0.01);
  ASSERT_GT(axis_angles.size(), 100u);
  std::sort(axis_angles.begin(), axis_angles.end());
  const double max_axis_angle = axis_angles.back();
  const double median_axis_angle = axis_angles[axis_angles.size() / 2];
  EXPECT_LT(max_axis_angle, 10.0);
  EXPECT_LT(median_axis_angle, 4.0);
  std::printf(
      "[ figures  ] route length %.2f m, cam1-cam0 offset %.4f m (max error "
      "%.4f m), optical axis vs travel: max %.2f deg, median %.2f deg\n",
      length, offset_sum / truth0.samples.size(), max_offset_error, max_axis_angle,
      median_axis_angle);
}

TEST_F(KittiRealData, SimulatesGnssDeterministically) {
  KittiImportOptions options;
  options.raw_drive_dir = kRawDrive;
  options.gps_noise_sigma_m = 3.0;
  options.seed = 1;
  const Drive a = ImportKitti(options);
  const Drive again = ImportKitti(options);
  options.seed = 2;
  const Drive other = ImportKitti(options);
  ASSERT_EQ(a.gnss.samples.size(), a.ground_truth->samples.size());
  EXPECT_EQ(a.gnss.samples, again.gnss.samples);
  EXPECT_FALSE(a.gnss.samples == other.gnss.samples);
  const auto mean_error = [](const Drive& drive) {
    double sum = 0;
    for (size_t i = 0; i < drive.gnss.samples.size(); ++i) {
      const PositionSample& truth = drive.ground_truth->samples[i];
      EXPECT_EQ(drive.gnss.samples[i].timestamp_s, truth.timestamp_s);
      sum += EnuFrame(truth.position).ToEnu(drive.gnss.samples[i].position).head<2>().norm();
    }
    return sum / drive.gnss.samples.size();
  };
  const double error = mean_error(a);
  EXPECT_GT(error, 0.5);
  EXPECT_LT(error, 10.0);
  std::printf(
      "[ figures  ] GNSS sigma 3 m: mean horizontal error %.2f m (seed 1), "
      "%.2f m (seed 2)\n",
      error, mean_error(other));
}

TEST_F(KittiRealData, ListsLidarScansWithPoses) {
  KittiImportOptions options;
  options.raw_drive_dir = kRawDrive;
  const Drive drive = ImportKitti(options);
  size_t num_bin = 0;
  for (const auto& entry : fs::directory_iterator(kRawDrive + "/velodyne_points/data")) {
    num_bin += entry.path().extension() == ".bin" ? 1 : 0;
  }
  EXPECT_EQ(num_bin, 31u);
  ASSERT_EQ(drive.lidar.size(), num_bin);
  double max_distance = 0;
  for (const LidarScan& scan : drive.lidar) {
    EXPECT_EQ(scan.format, "kitti_bin");
    EXPECT_TRUE(fs::exists(scan.path)) << scan.path;
    const PositionSample& camera = drive.ground_truth->samples.at(static_cast<size_t>(scan.scan));
    ASSERT_EQ(camera.frame, scan.scan);
    max_distance =
        std::max(max_distance, EnuFrame(camera.position).ToEnu(scan.sensor_position).norm());
    // The Velodyne's x axis (forward) is roughly the camera's z axis.
    const Eigen::Vector3d forward = scan.enu_from_sensor * Eigen::Vector3d::UnitX();
    EXPECT_GT(forward.dot(*camera.enu_from_cam * Eigen::Vector3d::UnitZ()), 0.99);
  }
  EXPECT_LT(max_distance, 2.0);
  // A selected span keeps the scans inside it, whatever the step.
  options.start = 10;
  options.stop = 50;
  options.step = 7;
  EXPECT_EQ(ImportKitti(options).lidar.size(), 8u);
}

}  // namespace
}  // namespace epiloc
