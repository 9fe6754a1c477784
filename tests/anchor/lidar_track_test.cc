#include "epiloc/anchor/lidar_track.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "anchor_test_util.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/kitti.h"
#include "test_util.h"

namespace epiloc {
namespace {

// The synthetic survey's scan poses are exact: the scans' own path is the track's.
TEST(LidarTrack, AnExactTrackNeedsNoCorrection) {
  const Drive survey = LoadDrive(SharedSyntheticWorld() + "/survey");
  ASSERT_GE(survey.lidar.size(), 4u);
  const EnuFrame frame(SynthOrigin());
  const LidarTrack track = EstimateLidarTrack(survey, frame, LidarTrackOptions());
  ASSERT_EQ(track.scans.size(), survey.lidar.size());
  ASSERT_EQ(track.steps.size(), survey.lidar.size() - 1);
  std::printf(
      "exact track: track / scans %.5f; direction pitch %+.3f heading %+.3f deg; turns within "
      "%.3f deg; corrections up to %.3f m\n",
      track.track_length_m / track.lidar_length_m, track.median_pitch_deg, track.median_heading_deg,
      track.max_turn_difference_deg, track.max_correction_m);
  for (const LidarTrackStep& s : track.steps) {
    std::printf("  scans %lld -> %lld: %.3f of the points on the surfaces, rms %.4f m\n",
                static_cast<long long>(s.from_scan), static_cast<long long>(s.to_scan),
                s.inlier_share, s.rms_m);
  }
  EXPECT_EQ(track.num_registered, static_cast<int>(track.steps.size()));
  EXPECT_NEAR(track.track_length_m / track.lidar_length_m, 1.0, 0.002);
  EXPECT_NEAR(track.median_pitch_deg, 0.0, 0.05);
  EXPECT_NEAR(track.median_heading_deg, 0.0, 0.05);
  EXPECT_LT(track.max_abs_pitch_deg, 0.1);
  EXPECT_LT(track.max_abs_heading_deg, 0.1);
  EXPECT_LT(track.max_turn_difference_deg, 0.05);
  EXPECT_LT(track.max_abs_cumulative_yaw_deg, 0.05);
  EXPECT_LT(track.max_correction_m, 0.03);
  for (const LidarTrackStep& s : track.steps) {
    EXPECT_EQ(s.to_scan, s.from_scan + (survey.lidar[1].scan - survey.lidar[0].scan));
    EXPECT_GT(s.inlier_share,
              0.4);  // the synthetic scans are 10 m apart (KITTI: 1.5-3.4 m, 0.6-0.8)
  }
}

// A track too short by 3 % whose direction of travel is 0.5 deg steeper than the road's (the
// shared KITTI drive's OXTS track is 3.7 % short and 0.4 deg flatter, README), its attitude exact:
// the scans' path gives both back, and the corrected drive's scans and ground truth lie where the
// exact ones do, up to one offset (the LiDAR does not know where on the Earth its path lies; it is
// placed at the track's mean).
TEST(LidarTrack, FindsAndUndoesAShortClimbingTrack) {
  const Drive exact = LoadDrive(SharedSyntheticWorld() + "/survey");
  ASSERT_TRUE(exact.ground_truth.has_value());
  const EnuFrame frame(SynthOrigin());
  const Eigen::Vector3d first = frame.ToEnu(exact.lidar.front().sensor_position);
  const double climb = std::tan(0.5 * M_PI / 180.0);
  const auto distort = [&](const Geodetic& g) {
    const Eigen::Vector3d x = frame.ToEnu(g);
    Eigen::Vector3d d = x - first;
    const double travelled = d.head<2>().norm();
    d.head<2>() /= 1.03;
    d.z() += climb * travelled / 1.03;
    return frame.ToGeodetic(first + d);
  };
  Drive drive = exact;
  for (LidarScan& scan : drive.lidar) scan.sensor_position = distort(scan.sensor_position);
  for (PositionSample& s : drive.ground_truth->samples) s.position = distort(s.position);

  const LidarTrack track = EstimateLidarTrack(drive, frame, LidarTrackOptions());
  EXPECT_EQ(track.num_registered, static_cast<int>(track.steps.size()));
  EXPECT_NEAR(track.track_length_m / track.lidar_length_m, 1.0 / 1.03, 0.003);
  EXPECT_NEAR(track.median_pitch_deg, 0.5 / 1.03, 0.05);
  EXPECT_NEAR(track.median_heading_deg, 0.0, 0.1);
  EXPECT_GT(track.max_correction_m, 0.3);

  const Drive corrected = CorrectDriveTrack(drive, frame, track);
  // The offset between the corrected and the exact scans, then the residual about it.
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < exact.lidar.size(); ++i) {
    offset += frame.ToEnu(corrected.lidar[i].sensor_position) -
              frame.ToEnu(exact.lidar[i].sensor_position);
  }
  offset /= static_cast<double>(exact.lidar.size());
  double max_scan = 0.0, max_truth = 0.0, max_distorted = 0.0;
  for (size_t i = 0; i < exact.lidar.size(); ++i) {
    const Eigen::Vector3d e = frame.ToEnu(exact.lidar[i].sensor_position) + offset;
    max_scan = std::max(max_scan, (frame.ToEnu(corrected.lidar[i].sensor_position) - e).norm());
    max_distorted =
        std::max(max_distorted, (frame.ToEnu(drive.lidar[i].sensor_position) - e).norm());
    EXPECT_TRUE(corrected.lidar[i].enu_from_sensor.isApprox(exact.lidar[i].enu_from_sensor));
  }
  const double t0 = exact.lidar.front().timestamp_s, t1 = exact.lidar.back().timestamp_s;
  for (size_t i = 0; i < exact.ground_truth->samples.size(); ++i) {
    const PositionSample& s = exact.ground_truth->samples[i];
    if (s.timestamp_s < t0 || s.timestamp_s > t1) continue;  // held beyond the scans
    const Eigen::Vector3d e = frame.ToEnu(s.position) + offset;
    max_truth =
        std::max(max_truth, (frame.ToEnu(corrected.ground_truth->samples[i].position) - e).norm());
  }
  std::printf("distorted track off by up to %.3f m; corrected scans %.3f m, ground truth %.3f m\n",
              max_distorted, max_scan, max_truth);
  EXPECT_GT(max_distorted, 0.5);
  EXPECT_LT(max_scan, 0.05);
  EXPECT_LT(max_truth, 0.08);  // between scans: linear in time, the car turns
  EXPECT_EQ(corrected.gnss.samples, drive.gnss.samples);  // the sensor under test is left alone
}

// A heading that turns away from the scans' (an INS whose heading drifts or over-turns; the
// shared drive's OXTS turns about 1 deg further than its scans through the last right turn,
// README): each scan's attitude turned about the up axis by 0.04 deg more than the one before,
// positions exact. Each pair's yaw difference and their running sum give it back, signed; the
// unsigned turn difference sees the same size.
TEST(LidarTrack, AHeadingThatTurnsAwayFromTheScansShowsInTheCumulativeYaw) {
  Drive drive = LoadDrive(SharedSyntheticWorld() + "/survey");
  ASSERT_GE(drive.lidar.size(), 4u);
  constexpr double kDegPerScan = 0.04;
  for (size_t i = 0; i < drive.lidar.size(); ++i) {
    const Eigen::AngleAxisd extra(kDegPerScan * static_cast<double>(i) * M_PI / 180.0,
                                  Eigen::Vector3d::UnitZ());
    drive.lidar[i].enu_from_sensor = (extra * drive.lidar[i].enu_from_sensor).normalized();
  }
  const LidarTrack track = EstimateLidarTrack(drive, EnuFrame(SynthOrigin()), LidarTrackOptions());
  ASSERT_EQ(track.num_registered, static_cast<int>(track.steps.size()));
  ASSERT_EQ(track.cumulative_yaw_deg.size(), drive.lidar.size());
  EXPECT_EQ(track.cumulative_yaw_deg.front(), 0.0);
  for (size_t i = 0; i < track.steps.size(); ++i) {
    EXPECT_NEAR(track.steps[i].yaw_difference_deg, kDegPerScan, 0.02) << i;
    EXPECT_NEAR(track.steps[i].turn_difference_deg, kDegPerScan, 0.02) << i;
  }
  const double expected = kDegPerScan * static_cast<double>(drive.lidar.size() - 1);
  EXPECT_NEAR(track.cumulative_yaw_deg.back(), expected, 0.05);
  EXPECT_NEAR(track.max_abs_cumulative_yaw_deg, expected, 0.05);
}

// A scan that is not what its pose says (here another place's scan file): the pairs with it do
// not register, keep the track's steps, and say why; the others are unaffected.
TEST(LidarTrack, APairThatDoesNotRegisterKeepsTheTracksStep) {
  Drive survey = LoadDrive(SharedSyntheticWorld() + "/survey");
  ASSERT_GE(survey.lidar.size(), 5u);
  survey.lidar[3].path = survey.ScanPath(survey.lidar[0]);
  const EnuFrame frame(SynthOrigin());
  const LidarTrack track = EstimateLidarTrack(survey, frame, LidarTrackOptions());
  EXPECT_EQ(track.num_registered, static_cast<int>(track.steps.size()) - 2);
  for (size_t i = 0; i < track.steps.size(); ++i) {
    const LidarTrackStep& s = track.steps[i];
    EXPECT_EQ(s.registered, i != 2 && i != 3) << i;
    if (!s.registered) {
      EXPECT_THAT(s.message, ::testing::HasSubstr("not registered")) << i;
    }
  }
  EXPECT_LT(track.max_correction_m, 0.03);
}

TEST(LidarTrack, RejectsBadInput) {
  const std::string world = SharedSyntheticWorld();
  const EnuFrame frame(SynthOrigin());
  const Drive survey = LoadDrive(world + "/survey");
  ExpectError([&] { EstimateLidarTrack(LoadDrive(world + "/query"), frame, {}); },
              {"query", "at least two scans", "has 0"});
  LidarTrackOptions options;
  options.max_range_m = 1.0;
  ExpectError([&] { EstimateLidarTrack(survey, frame, options); }, {"max_range_m"});
  options = LidarTrackOptions();
  options.min_inlier_share = 1.5;
  ExpectError([&] { EstimateLidarTrack(survey, frame, options); }, {"min_inlier_share"});
  // A track of other scans, or an empty one.
  LidarTrack track;
  ExpectError([&] { CorrectDriveTrack(survey, frame, track); }, {"empty"});
  track.scans = {survey.lidar.front().scan + 100000};
  track.timestamps_s = {0.0};
  track.correction_m = {Eigen::Vector3d::Zero()};
  ExpectError([&] { CorrectDriveTrack(survey, frame, track); }, {"scan", "not in the LiDAR track"});
  track.scans = {survey.lidar.front().scan};
  Drive one = survey;
  one.lidar.resize(1);
  ExpectError([&] { CorrectDriveTrack(one, frame, track); }, {"was taken at"});
}

// The shared KITTI drive (skipped without ../shared/data): its OXTS track, as imported, steps
// 3.7 % short of its scans and its direction of travel is 0.4 deg flatter than theirs (it climbs
// 0.5 m less over the 69 m), while its turns agree
// with theirs within about 0.1 deg per pair (README). Those small differences add up: through
// the drive's last right turn (frames 65-150, 70 deg) the OXTS heading turns 1.07 deg further
// than the scans (1.5 % of the turn; through the first, left turn within 0.13 deg), measured
// 2026-12-06. Recorded so that an import that fixes it, or one that makes it worse, is noticed.
TEST(LidarTrack, TheSharedKittiDrivesTrackAgainstItsScans) {
  namespace fs = std::filesystem;
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  KittiImportOptions import;
  import.raw_drive_dir = raw.string();
  const Drive drive = ImportKitti(import);
  const LidarTrack track =
      EstimateLidarTrack(drive, EnuFrame(drive.lidar.front().sensor_position), LidarTrackOptions());
  std::printf(
      "KITTI: %d of %zu pairs registered; track / scans %.4f; direction pitch %+.3f heading "
      "%+.3f deg; turns within %.3f deg, heading away from the scans' by %+.3f deg at the end; "
      "corrections up to %.2f m\n",
      track.num_registered, track.steps.size(), track.track_length_m / track.lidar_length_m,
      track.median_pitch_deg, track.median_heading_deg, track.max_turn_difference_deg,
      track.cumulative_yaw_deg.back(), track.max_correction_m);
  EXPECT_EQ(track.num_registered, static_cast<int>(track.steps.size()));
  EXPECT_GT(track.track_length_m / track.lidar_length_m, 0.95);
  EXPECT_LT(track.track_length_m / track.lidar_length_m, 0.975);
  EXPECT_LT(track.median_pitch_deg, -0.25);
  EXPECT_GT(track.median_pitch_deg, -0.6);
  EXPECT_GT(track.max_abs_heading_deg, 2.0);  // in the square, frames 55-90
  EXPECT_LT(track.max_turn_difference_deg, 0.2);
  EXPECT_LT(track.cumulative_yaw_deg.back(), -0.7);
  EXPECT_GT(track.cumulative_yaw_deg.back(), -1.4);
  for (const LidarTrackStep& s : track.steps) EXPECT_GT(s.inlier_share, 0.5);
}

}  // namespace
}  // namespace epiloc
