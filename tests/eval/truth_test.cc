#include "epiloc/eval/truth.h"

#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/io/kitti.h"
#include "eval_test_util.h"

namespace epiloc {
namespace {

Eigen::Vector3d Enu(const PositionSample& sample) {
  return EnuFrame(TestOrigin()).ToEnu(sample.position);
}

TruthOptions WithOrigin(TruthFormat format = TruthFormat::kAuto, double yaw_deg = 0.0) {
  TruthOptions options;
  options.format = format;
  options.origin = TestOrigin();
  options.yaw_deg = yaw_deg;
  return options;
}

TEST(Truth, ParsesFormatNames) {
  EXPECT_EQ(ParseTruthFormat("kitti_poses"), TruthFormat::kKittiPoses);
  EXPECT_EQ(TruthFormatName(TruthFormat::kNdt), "ndt");
  ExpectError([] { ParseTruthFormat("bag"); }, {"unknown ground-truth format 'bag'", "tum"});
}

TEST(Truth, ReadsTumWithYaw) {
  TempDir dir;
  WriteText(dir / "t.tum", "# t x y z qx qy qz qw\n1.0 1 0 0 0 0 0 1\n1.5 0 2 0.5 0 0 0 1\n");
  EXPECT_EQ(DetectTruthFormat(dir / "t.tum"), TruthFormat::kTum);
  // Yaw 90 deg: pose x -> ENU north, pose y -> ENU west.
  const PositionTrack track = ReadTruth(dir / "t.tum", WithOrigin(TruthFormat::kAuto, 90.0));
  ASSERT_EQ(track.samples.size(), 2u);
  EXPECT_EQ(track.samples[1].timestamp_s, 1.5);
  EXPECT_LT((Enu(track.samples[0]) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-6);
  EXPECT_LT((Enu(track.samples[1]) - Eigen::Vector3d(-2, 0, 0.5)).norm(), 1e-6);
  EXPECT_EQ(track.samples[0].frame, kInvalidFrame);
}

TEST(Truth, ReadsKittiPosesInCameraAxes) {
  TempDir dir;
  // t = (x right 1, y down 2, z forward 3) -> ENU (east 1, north 3, up -2) at yaw 0.
  WriteText(dir / "poses.txt",
            "1 0 0 0 0 1 0 0 0 0 1 0\n"
            "1 0 0 1 0 1 0 2 0 0 1 3\n");
  WriteText(dir / "times.txt", "10.0\n10.1\n");
  EXPECT_EQ(DetectTruthFormat(dir / "poses.txt"), TruthFormat::kKittiPoses);
  TruthOptions options = WithOrigin();
  options.times_path = dir / "times.txt";
  PositionTrack track = ReadTruth(dir / "poses.txt", options);
  ASSERT_EQ(track.samples.size(), 2u);
  EXPECT_EQ(track.samples[1].frame, 1);
  EXPECT_EQ(track.samples[1].timestamp_s, 10.1);
  EXPECT_LT(Enu(track.samples[0]).norm(), 1e-6);
  EXPECT_LT((Enu(track.samples[1]) - Eigen::Vector3d(1, 3, -2)).norm(), 1e-6);
  // Without times: time = line index, frame = line index.
  options.times_path.clear();
  track = ReadTruth(dir / "poses.txt", options);
  EXPECT_EQ(track.samples[1].timestamp_s, 1.0);
  WriteText(dir / "short_times.txt", "10.0\n");
  options.times_path = dir / "short_times.txt";
  ExpectError([&] { ReadTruth(dir / "poses.txt", options); }, {dir / "poses.txt:2", "timestamp"});
}

TEST(Truth, ReadsNdtWithAndWithoutHeaderAndLeverArm) {
  TempDir dir;
  WriteText(dir / "plain.csv", "5.0,1,2,3,0,0,0\n5.1,2,2,3,0,0,1.5707963267948966\n");
  EXPECT_EQ(DetectTruthFormat(dir / "plain.csv"), TruthFormat::kNdt);
  TruthOptions options = WithOrigin();
  PositionTrack track = ReadTruth(dir / "plain.csv", options);
  ASSERT_EQ(track.samples.size(), 2u);
  EXPECT_LT((Enu(track.samples[0]) - Eigen::Vector3d(1, 2, 3)).norm(), 1e-6);
  // Lever arm 1 m forward: the second sensor faces north (yaw 90 deg).
  options.lever_arm_m = Eigen::Vector3d(1, 0, 0);
  track = ReadTruth(dir / "plain.csv", options);
  EXPECT_LT((Enu(track.samples[0]) - Eigen::Vector3d(2, 2, 3)).norm(), 1e-6);
  EXPECT_LT((Enu(track.samples[1]) - Eigen::Vector3d(2, 3, 3)).norm(), 1e-6);

  WriteText(dir / "header.csv", "time,x,y,z,roll,pitch,yaw,frame\n7,4,5,6,0,0,0,11\n");
  EXPECT_EQ(DetectTruthFormat(dir / "header.csv"), TruthFormat::kNdt);
  track = ReadTruth(dir / "header.csv", WithOrigin());
  ASSERT_EQ(track.samples.size(), 1u);
  EXPECT_EQ(track.samples[0].frame, 11);
  EXPECT_EQ(track.samples[0].timestamp_s, 7.0);
  EXPECT_LT((Enu(track.samples[0]) - Eigen::Vector3d(4, 5, 6)).norm(), 1e-6);
  WriteText(dir / "no_yaw.csv", "time,x,y,z,roll,pitch\n7,4,5,6,0,0\n");
  ExpectError([&] { ReadTruth(dir / "no_yaw.csv", WithOrigin(TruthFormat::kNdt)); },
              {dir / "no_yaw.csv:1", "yaw"});
  WriteText(dir / "bad.csv", "5.0,1,2,3,0,0,0\n5.1,2,2,x,0,0,0\n");
  ExpectError([&] { ReadTruth(dir / "bad.csv", WithOrigin()); }, {dir / "bad.csv:2", "7 numbers"});
}

TEST(Truth, ReadsPositionCsv) {
  TempDir dir;
  WriteText(dir / "p.csv",
            "timestamp_s,lat_deg,lon_deg,alt_m,frame\n1,49,8.4,100,3\n2,49.00001,8.4,100,4\n");
  EXPECT_EQ(DetectTruthFormat(dir / "p.csv"), TruthFormat::kCsv);
  const PositionTrack track = ReadTruth(dir / "p.csv", TruthOptions());
  ASSERT_EQ(track.samples.size(), 2u);
  EXPECT_EQ(track.samples[1].frame, 4);
  EXPECT_EQ(track.samples[1].position.lat_deg, 49.00001);
}

TEST(Truth, ReadsKittiOxtsFolderAndMovesItByTheLeverArm) {
  TempDir dir;
  const std::string drive = WriteMiniKitti(dir.str(), 3);
  EXPECT_EQ(DetectTruthFormat(drive + "/oxts"), TruthFormat::kKittiOxts);
  EXPECT_EQ(DetectTruthFormat(drive), TruthFormat::kKittiOxts);  // raw drive folder with oxts/
  TruthOptions options;
  PositionTrack track = ReadTruth(drive, options);
  ASSERT_EQ(track.samples.size(), 3u);
  EXPECT_EQ(track.samples[2].frame, 2);
  EXPECT_NEAR(track.samples[2].position.lat_deg, 49.00002, 1e-12);
  // The IMU faces north (yaw 90 deg): 1 m forward and 0.5 m left = 1 m north, 0.5 m west.
  options.lever_arm_m = Eigen::Vector3d(1.0, 0.5, 0.0);
  track = ReadTruth(drive, options);
  const EnuFrame at_first(Geodetic{49.0, 8.4, 100.0});
  EXPECT_LT((at_first.ToEnu(track.samples[0].position) - Eigen::Vector3d(-0.5, 1.0, 0)).norm(),
            1e-6);
}

TEST(Truth, ReadsDriveGroundTruth) {
  TempDir dir;
  KittiImportOptions import;
  import.raw_drive_dir = WriteMiniKitti(dir / "raw", 3);
  import.out_dir = dir / "drive";
  ImportKitti(import);
  EXPECT_EQ(DetectTruthFormat(dir / "drive"), TruthFormat::kDrive);
  const PositionTrack track = ReadTruth(dir / "drive", TruthOptions());
  ASSERT_EQ(track.samples.size(), 3u);
  EXPECT_EQ(track.samples[1].frame, 1);
  EXPECT_NEAR(track.samples[1].position.lat_deg, 49.00001, 1e-12);
}

TEST(Truth, RejectsBadInput) {
  TempDir dir;
  WriteText(dir / "t.tum", "1.0 1 0 0 0 0 0 1\n2.0 1 0 0 0 0 1\n");
  ExpectError([&] { ReadTruth(dir / "t.tum", WithOrigin(TruthFormat::kTum)); },
              {dir / "t.tum:2", "expected 8 numbers"});
  WriteText(dir / "back.tum", "2.0 1 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n");
  ExpectError([&] { ReadTruth(dir / "back.tum", WithOrigin()); },
              {dir / "back.tum:2", "not after"});
  WriteText(dir / "nan.tum", "1.0 nan 0 0 0 0 0 1\n");
  ExpectError([&] { ReadTruth(dir / "nan.tum", WithOrigin(TruthFormat::kTum)); },
              {dir / "nan.tum:1"});
  TruthOptions no_origin;
  WriteText(dir / "ok.tum", "1.0 1 0 0 0 0 0 1\n");
  ExpectError([&] { ReadTruth(dir / "ok.tum", no_origin); }, {dir / "ok.tum", "--truth-origin"});
  WriteText(dir / "what.txt", "hello world\n");
  ExpectError([&] { DetectTruthFormat(dir / "what.txt"); }, {dir / "what.txt", "--truth-format"});
  ExpectError([&] { DetectTruthFormat(dir / "absent"); }, {dir / "absent"});
  WriteText(dir / "empty.tum", "# nothing\n");
  ExpectError([&] { ReadTruth(dir / "empty.tum", WithOrigin(TruthFormat::kTum)); },
              {dir / "empty.tum", "no positions"});
  TruthOptions lever = WithOrigin(TruthFormat::kTum);
  lever.lever_arm_m = Eigen::Vector3d(1, 0, 0);
  ExpectError([&] { ReadTruth(dir / "ok.tum", lever); }, {"--truth-lever-arm", "tum"});
  TruthOptions bad_origin;
  bad_origin.origin = Geodetic{95.0, 0.0, 0.0};
  ExpectError([&] { ReadTruth(dir / "ok.tum", bad_origin); }, {"--truth-origin", "95"});
}

}  // namespace
}  // namespace epiloc
