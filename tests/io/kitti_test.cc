#include "epiloc/io/kitti.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "epiloc/geo/rigid3.h"
#include "io_test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

const std::string kRawDrive = KittiRawDrive().string();

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

// --frame-time trigger: a frame's time is the Velodyne's forward-facing time (20 ms before the
// OXTS record here), and its truth the camera track interpolated there, the drive's first frame
// extrapolated from the first two records; the image timestamps otherwise. Without the
// Velodyne's timestamps it is an error naming the file. The default (auto) takes the trigger
// times when they are there, the image timestamps when not.
TEST(KittiImport, TriggerTimesPutTheTruthAtTheVelodyneTimes) {
  MiniKitti kitti;
  KittiImportOptions options = kitti.Options(0);
  options.frame_time = KittiImportOptions::FrameTime::kTrigger;
  ExpectError([&] { ImportKitti(options); }, {"velodyne_points/timestamps.txt", "not found"});
  KittiImportOptions image_options = kitti.Options(0);
  image_options.frame_time = KittiImportOptions::FrameTime::kImage;
  const Drive without_trigger_times = ImportKitti(kitti.Options(0));
  EXPECT_EQ(without_trigger_times.frames, ImportKitti(image_options).frames);
  std::string trigger_times;
  for (int i = 0; i < 4; ++i) {
    trigger_times += fmt::format("2011-09-26 13:04:{:012.9f}\n", 32.0 + 0.1 * i - 0.02);
  }
  WriteText(kitti.drive() + "/velodyne_points/timestamps.txt", trigger_times);
  const Drive at_image = ImportKitti(image_options);
  const Drive at_trigger = ImportKitti(options);
  EXPECT_EQ(without_trigger_times.frames, at_image.frames);
  const Drive by_default = ImportKitti(kitti.Options(0));
  EXPECT_EQ(by_default.frames, at_trigger.frames);
  EXPECT_EQ(by_default.ground_truth->samples, at_trigger.ground_truth->samples);
  ASSERT_EQ(at_trigger.frames.size(), 4u);
  ASSERT_EQ(at_trigger.ground_truth->samples.size(), 4u);
  const std::vector<PositionSample>& image = at_image.ground_truth->samples;
  const std::vector<PositionSample>& trigger = at_trigger.ground_truth->samples;
  const EnuFrame enu(image[0].position);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_NEAR(at_trigger.frames[i].timestamp_s, at_image.frames[i].timestamp_s - 0.025, 1e-6);
    EXPECT_EQ(trigger[i].frame, static_cast<frame_t>(i));
    EXPECT_NEAR(trigger[i].timestamp_s, at_trigger.frames[i].timestamp_s, 1e-9);
    // 0.2 of the way back to the record before (the first: ahead of the second, extrapolated).
    const size_t j = i == 0 ? 1 : i - 1;
    const double w = i == 0 ? -0.2 : 0.2;
    const Eigen::Vector3d expected = (1.0 - w) * Enu(enu, image[i]) + w * Enu(enu, image[j]);
    EXPECT_LT((Enu(enu, trigger[i]) - expected).norm(), 1e-6) << i;
    EXPECT_GT((Enu(enu, trigger[i]) - Enu(enu, image[i])).norm(), 0.2) << i;
    EXPECT_LT(trigger[i].enu_from_cam->angularDistance(*image[i].enu_from_cam), 1e-9);
  }
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

// A vehicle driving north at 10 m/s, sampled every 0.1 s, whose recorded positions squeeze
// samples 10-19 (0.9 m steps) and then keep the 1 m lag: the velocity is exact.
std::vector<OxtsRecord> SqueezedRecords(double position_accuracy, double velocity_accuracy) {
  std::vector<OxtsRecord> records;
  const EnuFrame enu({49.0, 8.4, 100.0});
  double recorded_north = 0;
  for (int i = 0; i < 30; ++i) {
    if (i > 0) recorded_north += (i >= 10 && i < 20) ? 0.9 : 1.0;
    OxtsRecord r;
    r.frame = i;
    r.timestamp_s = 1e9 + 0.1 * i;
    r.position = enu.ToGeodetic(Eigen::Vector3d(0, recorded_north, 0));
    r.values.assign(30, 0.0);
    r.values[6] = 10.0;  // vn
    r.values[23] = position_accuracy;
    r.values[24] = velocity_accuracy;
    records.push_back(r);
  }
  return records;
}

TEST(KittiOxts, FusedPositionsFollowTheVelocity) {
  const std::vector<OxtsRecord> records = SqueezedRecords(0.5, 0.02);
  const FusedOxts fused = FuseOxtsPositions(records);
  ASSERT_TRUE(fused.fused) << fused.why_not;
  ASSERT_EQ(fused.positions.size(), records.size());
  const EnuFrame enu(records.front().position);
  // Equal position weights and an exact velocity: the track is the true one (i * 1 m) moved by
  // the mean of the recorded positions' errors, which are 0 up to sample 9, then -0.1 ... -1 m.
  double mean_error = 0;
  for (size_t i = 0; i < records.size(); ++i) {
    mean_error += enu.ToEnu(records[i].position).y() - static_cast<double>(i);
  }
  mean_error /= static_cast<double>(records.size());
  double max_step_error = 0, max_offset_error = 0;
  for (size_t i = 0; i < records.size(); ++i) {
    const Eigen::Vector3d p = enu.ToEnu(fused.positions[i]);
    max_offset_error =
        std::max(max_offset_error, std::abs(p.y() - static_cast<double>(i) - mean_error));
    EXPECT_NEAR(p.x(), 0.0, 1e-6);
    if (i > 0) {
      const double step = p.y() - enu.ToEnu(fused.positions[i - 1]).y();
      max_step_error = std::max(max_step_error, std::abs(step - 1.0));
    }
  }
  // The squeeze would need a velocity error of 1 m/s, 50 of its sigmas: the steps keep to 1 m
  // (the slow velocity error takes up a few millimetres).
  EXPECT_LT(max_step_error, 0.01);
  EXPECT_LT(max_offset_error, 0.03);
  // The first samples move by -mean_error, the last (recorded 1 m behind) by 1 + mean_error.
  EXPECT_NEAR(fused.max_correction_m, std::max(-mean_error, 1.0 + mean_error), 0.02);
}

TEST(KittiOxts, RecordsWithoutAccuraciesStayAsRecorded) {
  const std::vector<OxtsRecord> records = SqueezedRecords(0.0, 0.02);
  const FusedOxts fused = FuseOxtsPositions(records);
  EXPECT_FALSE(fused.fused);
  EXPECT_NE(fused.why_not.find("record 0"), std::string::npos) << fused.why_not;
  for (size_t i = 0; i < records.size(); ++i) {
    EXPECT_EQ(fused.positions[i].lat_deg, records[i].position.lat_deg);
    EXPECT_EQ(fused.positions[i].alt_m, records[i].position.alt_m);
  }
  EXPECT_FALSE(FuseOxtsPositions({records.front()}).fused);
  std::vector<OxtsRecord> broken = SqueezedRecords(0.5, 0.02);
  broken[7].values[6] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(FuseOxtsPositions(broken).why_not.find("record 7"), std::string::npos);
  broken[7].values[6] = 1e300;
  EXPECT_FALSE(FuseOxtsPositions(broken).fused);
  // MiniKitti's records carry zeros: imported as recorded, whatever the option says.
  MiniKitti kitti;
  const Drive drive = ImportKitti(kitti.Options(0));
  EXPECT_NEAR(drive.ground_truth->samples[2].position.lat_deg, 49.00002, 1e-12);
}

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
  // The trigger time (velodyne_points/timestamps.txt), 17 ms before the image's timestamp.
  EXPECT_NEAR(cam0.frames[0].timestamp_s, 1317042272.335337762, 1e-6);
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

// The imported camera track against the INS velocity: how far the optical axis points from the
// direction of travel (over +-1 sample, 0.3-0.7 m), median and max in degrees, and the steps'
// lengths over the open square (frames 3-15, 49-71) relative to speed * dt.
struct TrackConsistency {
  double median_axis_deg = 0, max_axis_deg = 0;
  double min_step_ratio = 1e9, max_step_ratio = 0;
};
TrackConsistency Consistency(const Drive& drive) {
  const std::vector<OxtsRecord> oxts = ReadKittiOxts(kRawDrive + "/oxts");
  const PositionTrack& truth = *drive.ground_truth;
  const EnuFrame frame(truth.samples.front().position);
  std::vector<double> angles;
  TrackConsistency c;
  for (size_t i = 1; i + 1 < truth.samples.size(); ++i) {
    const Eigen::Vector3d travel =
        Enu(frame, truth.samples[i + 1]) - Enu(frame, truth.samples[i - 1]);
    const Eigen::Vector3d axis = *truth.samples[i].enu_from_cam * Eigen::Vector3d::UnitZ();
    angles.push_back(std::acos(std::min(1.0, axis.dot(travel.normalized()))) * 180 / M_PI);
    const frame_t f = truth.samples[i].frame;
    if ((f >= 3 && f <= 15) || (f >= 49 && f <= 71)) {
      const double step = (Enu(frame, truth.samples[i]) - Enu(frame, truth.samples[i - 1])).norm();
      const double speed = 0.5 * (std::hypot(oxts[i].values[6], oxts[i].values[7]) +
                                  std::hypot(oxts[i - 1].values[6], oxts[i - 1].values[7]));
      const double dt = truth.samples[i].timestamp_s - truth.samples[i - 1].timestamp_s;
      const double ratio = step / (speed * dt);
      c.min_step_ratio = std::min(c.min_step_ratio, ratio);
      c.max_step_ratio = std::max(c.max_step_ratio, ratio);
    }
  }
  std::sort(angles.begin(), angles.end());
  c.median_axis_deg = angles[angles.size() / 2];
  c.max_axis_deg = angles.back();
  return c;
}

TEST_F(KittiRealData, FusedPositionsAgreeWithTheVelocityAndTheCamera) {
  KittiImportOptions options;
  options.raw_drive_dir = kRawDrive;
  options.oxts_positions = KittiImportOptions::OxtsPositions::kRaw;
  const TrackConsistency raw = Consistency(ImportKitti(options));
  options.oxts_positions = KittiImportOptions::OxtsPositions::kFused;
  const Drive drive = ImportKitti(options);
  const TrackConsistency fused = Consistency(drive);
  std::printf(
      "[ figures  ] camera axis vs travel over one sample: raw median %.2f max %.2f deg, fused "
      "median %.2f max %.2f deg; square step / (speed dt): raw %.3f..%.3f, fused %.3f..%.3f\n",
      raw.median_axis_deg, raw.max_axis_deg, fused.median_axis_deg, fused.max_axis_deg,
      raw.min_step_ratio, raw.max_step_ratio, fused.min_step_ratio, fused.max_step_ratio);
  // Recorded: steps squeezed to 82 % of the velocity's in the square; fused: within 8 %.
  EXPECT_LT(raw.min_step_ratio, 0.85);
  EXPECT_GT(fused.min_step_ratio, 0.92);
  EXPECT_LT(fused.max_step_ratio, 1.03);
  // The rest of the median is the camera's mounting and the car's slip, not the track.
  EXPECT_LT(fused.median_axis_deg, 0.85 * raw.median_axis_deg);
  EXPECT_LT(fused.max_axis_deg, 0.6 * raw.max_axis_deg);
  // Still the GNSS's track: no position moved by more than about two of its reported sigmas
  // (0.3-0.5 m).
  const FusedOxts moved = FuseOxtsPositions(ReadKittiOxts(kRawDrive + "/oxts"));
  ASSERT_TRUE(moved.fused);
  EXPECT_LT(moved.max_correction_m, 1.0);
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
