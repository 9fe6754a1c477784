#include "epiloc/georef/trajectory_import.h"

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "stella_map_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

// ORB-SLAM-style TUM lines: a comment, a blank line, three poses; the second quaternion is a
// 90 degree turn about the camera's y axis written slightly off unit length.
const char kTum[] =
    "# timestamp tx ty tz qx qy qz qw\n"
    "\n"
    "1317380000.0 0 0 0 0 0 0 1\n"
    "1317380000.1 0.5 -0.1 2.0 0 0.7071 0 0.7072\n"
    "  1317380000.2\t1.0 -0.2 4.0 0 0 0 1  \n";

// KITTI poses: identity, then 1 m forward (z), then 2 m forward turned 90 degrees about y.
const char kKitti[] =
    "1 0 0 0 0 1 0 0 0 0 1 0\n"
    "1 0 0 0 0 1 0 0 0 0 1 1\n"
    "0 0 1 0 0 1 0 0 -1 0 0 2\n";

TEST(TrajectoryImport, FormatNames) {
  EXPECT_EQ(ParseTrajectoryFileFormat("auto"), TrajectoryFileFormat::kAuto);
  EXPECT_EQ(ParseTrajectoryFileFormat("tum"), TrajectoryFileFormat::kTum);
  EXPECT_EQ(ParseTrajectoryFileFormat("kitti"), TrajectoryFileFormat::kKitti);
  EXPECT_EQ(ParseTrajectoryFileFormat("stella_map"), TrajectoryFileFormat::kStellaMap);
  ExpectError([] { ParseTrajectoryFileFormat("euroc"); }, {"unknown trajectory format 'euroc'"});
}

TEST(TrajectoryImport, ReadsTum) {
  TempDir dir;
  WriteText(dir / "vo.tum", kTum);
  const ImportedTrajectory t = ImportTrajectory(dir / "vo.tum", TrajectoryImportOptions());
  EXPECT_EQ(t.path, dir / "vo.tum");
  EXPECT_EQ(t.format, TrajectoryFileFormat::kTum);  // auto: 8 numbers
  ASSERT_EQ(t.poses.size(), 3u);
  EXPECT_DOUBLE_EQ(t.poses[0].timestamp_s, 1317380000.0);
  EXPECT_DOUBLE_EQ(t.poses[2].timestamp_s, 1317380000.2);
  EXPECT_EQ(t.poses[1].line, 4);
  EXPECT_LT((t.poses[1].world_from_cam.translation - Eigen::Vector3d(0.5, -0.1, 2.0)).norm(),
            1e-12);
  EXPECT_NEAR(t.poses[1].world_from_cam.rotation.norm(), 1.0, 1e-12);  // normalised
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()));
  EXPECT_LT(RotationDifferenceDeg(t.poses[1].world_from_cam.rotation, turn), 0.01);
  EXPECT_LT((t.poses[2].world_from_cam.translation - Eigen::Vector3d(1.0, -0.2, 4.0)).norm(),
            1e-12);
}

TEST(TrajectoryImport, TumTimesOnTheDriveClock) {
  TempDir dir;
  // ORB-SLAM3 on EuRoC-style data: nanoseconds.
  WriteText(dir / "ns.tum",
            "1317380000000000000 0 0 0 0 0 0 1\n"
            "1317380000100000000 0 0 1 0 0 0 1\n");
  const ImportedTrajectory ns = ImportTrajectory(dir / "ns.tum", TrajectoryImportOptions());
  ASSERT_EQ(ns.poses.size(), 2u);
  EXPECT_NEAR(ns.poses[0].timestamp_s, 1317380000.0, 1e-6);
  EXPECT_NEAR(ns.poses[1].timestamp_s, 1317380000.1, 1e-6);
  // Seconds since the start, put on the drive's clock by an offset or by the first frame's time.
  WriteText(dir / "rel.tum",
            "0.0 0 0 0 0 0 0 1\n"
            "0.1 0 0 1 0 0 0 1\n");
  TrajectoryImportOptions options;
  options.format = TrajectoryFileFormat::kTum;
  options.time_offset_s = 1000.0;
  EXPECT_DOUBLE_EQ(ImportTrajectory(dir / "rel.tum", options).poses[1].timestamp_s, 1000.1);
  options = TrajectoryImportOptions();
  options.relative_times = true;
  options.frame_times = {500.0, 500.1, 500.2};
  EXPECT_DOUBLE_EQ(ImportTrajectory(dir / "rel.tum", options).poses[1].timestamp_s, 500.1);
}

// TUM poses carry the drive's frame numbers when its frames are given (issue 17: georef rows
// had none), and the drive an `epiloc vo` file names is found.
TEST(TrajectoryImport, TumPosesTakeFrameNumbers) {
  TempDir dir;
  WriteText(dir / "vo.tum", std::string("# epiloc vo\n# drive_dir /data/drives/cam1\n") + kTum);
  EXPECT_EQ(TrajectoryDriveDir(dir / "vo.tum"), "/data/drives/cam1");
  WriteText(dir / "plain.tum", kTum);
  EXPECT_EQ(TrajectoryDriveDir(dir / "plain.tum"), "");
  TrajectoryImportOptions options;
  options.frame_times = {1317379999.9, 1317380000.0, 1317380000.1004, 1317380000.3};
  options.frame_numbers = {10, 11, 12, 13};
  const ImportedTrajectory t = ImportTrajectory(dir / "vo.tum", options);
  ASSERT_EQ(t.poses.size(), 3u);
  EXPECT_EQ(t.poses[0].frame, 11);
  EXPECT_EQ(t.poses[1].frame, 12);           // 0.4 ms apart: the same frame
  EXPECT_EQ(t.poses[2].frame, kInvalidFrame);  // no frame at that time
  options.frame_numbers.pop_back();
  ExpectError([&] { ImportTrajectory(dir / "vo.tum", options); },
              {"3 frame numbers for 4 frame times"});
}

// stella_vslam's map.msg (io/stella_map.h): its keyframes, in time order, recognised by the
// file's first byte and put on the drive's clock and frames like a TUM file.
TEST(TrajectoryImport, ReadsAStellaMapsKeyframes) {
  TempDir dir;
  const Rigid3d turned(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())),
                       Eigen::Vector3d(0.5, -0.1, 2.0));
  WriteMessagePack(StellaMapJson({{4, 0.2, turned, {}}, {0, 0.0, Rigid3d(), {}}}, {}),
                   dir / "map.msg");
  TrajectoryImportOptions options;
  options.relative_times = true;
  options.frame_times = {500.0, 500.1, 500.2};
  options.frame_numbers = {7, 8, 9};
  StellaMap map;
  const ImportedTrajectory t = ImportTrajectory(dir / "map.msg", options, &map);
  EXPECT_EQ(t.format, TrajectoryFileFormat::kStellaMap);
  ASSERT_EQ(map.keyframes.size(), 2u);  // the map as read, before the re-timing
  EXPECT_EQ(map.keyframes[1].timestamp_s, 0.2);
  EXPECT_EQ(map.keyframe_ids, (std::vector<int64_t>{0, 4}));
  ASSERT_EQ(t.poses.size(), 2u);
  EXPECT_DOUBLE_EQ(t.poses[0].timestamp_s, 500.0);
  EXPECT_EQ(t.poses[0].frame, 7);
  EXPECT_EQ(t.poses[1].frame, 9);
  EXPECT_LT((t.poses[1].world_from_cam.translation - turned.translation).norm(), 1e-12);
  EXPECT_LT(RotationDifferenceDeg(t.poses[1].world_from_cam.rotation, turned.rotation), 1e-9);
  EXPECT_EQ(TrajectoryDriveDir(dir / "map.msg"), "");
  options.times_path = dir / "times.txt";
  ExpectError([&] { ImportTrajectory(dir / "map.msg", options); },
              {"a times file applies to KITTI poses only"});
}

TEST(TrajectoryImport, ReadsKittiWithEachSourceOfTimes) {
  TempDir dir;
  WriteText(dir / "poses.txt", kKitti);
  // No times: line i is i seconds.
  ImportedTrajectory t = ImportTrajectory(dir / "poses.txt", TrajectoryImportOptions());
  EXPECT_EQ(t.format, TrajectoryFileFormat::kKitti);  // auto: 12 numbers
  ASSERT_EQ(t.poses.size(), 3u);
  EXPECT_EQ(t.poses[2].frame, 2);
  EXPECT_DOUBLE_EQ(t.poses[2].timestamp_s, 2.0);
  EXPECT_LT((t.poses[1].world_from_cam.translation - Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
  EXPECT_LT((t.poses[2].world_from_cam.translation - Eigen::Vector3d(0, 0, 2)).norm(), 1e-12);
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()));
  EXPECT_LT(RotationDifferenceDeg(t.poses[2].world_from_cam.rotation, turn), 1e-9);
  // ORB-SLAM's times.txt (seconds since the start) plus an offset.
  WriteText(dir / "times.txt", "0.0\n0.103\n0.207\n");
  TrajectoryImportOptions options;
  options.times_path = dir / "times.txt";
  options.time_offset_s = 1000.0;
  t = ImportTrajectory(dir / "poses.txt", options);
  EXPECT_DOUBLE_EQ(t.poses[1].timestamp_s, 1000.103);
  EXPECT_DOUBLE_EQ(t.poses[2].timestamp_s, 1000.207);
  // The drive's frame times, one per pose.
  options = TrajectoryImportOptions();
  options.frame_times = {500.0, 500.1, 500.2};
  t = ImportTrajectory(dir / "poses.txt", options);
  EXPECT_DOUBLE_EQ(t.poses[0].timestamp_s, 500.0);
  EXPECT_DOUBLE_EQ(t.poses[2].timestamp_s, 500.2);
  // Those are already on the drive's clock: --relative-times (which the command line asks for
  // together with --drive) must not add the first frame's time a second time.
  options.relative_times = true;
  t = ImportTrajectory(dir / "poses.txt", options);
  EXPECT_DOUBLE_EQ(t.poses[0].timestamp_s, 500.0);
  EXPECT_DOUBLE_EQ(t.poses[2].timestamp_s, 500.2);
  // With a times file, --relative-times puts the file's times on the drive's clock.
  options.times_path = dir / "times.txt";
  t = ImportTrajectory(dir / "poses.txt", options);
  EXPECT_DOUBLE_EQ(t.poses[1].timestamp_s, 500.103);
}

TEST(TrajectoryImport, BadInputNamesFileAndLine) {
  TempDir dir;
  const std::string path = dir / "bad.tum";
  // A line with 7 numbers.
  WriteText(path, "# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n");
  ExpectError([&] { ImportTrajectory(path, TrajectoryImportOptions()); },
              {path + ":3", "expected 8 numbers"});
  // A word.
  WriteText(path, "1 0 0 0 0 0 0 1\n2 0 0 x 0 0 0 1\n");
  ExpectError([&] { ImportTrajectory(path, TrajectoryImportOptions()); },
              {path + ":2", "'2 0 0 x"});
  // Not a unit quaternion.
  WriteText(path, "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 2\n");
  ExpectError([&] { ImportTrajectory(path, TrajectoryImportOptions()); },
              {path + ":2", "not of unit length"});
  // Time going backwards.
  WriteText(path, "1 0 0 0 0 0 0 1\n\n0.5 0 0 0 0 0 0 1\n");
  ExpectError([&] { ImportTrajectory(path, TrajectoryImportOptions()); },
              {path + ":3", "not after the previous one"});
  // NaN.
  WriteText(path, "1 0 0 nan 0 0 0 1\n");
  ExpectError([&] { ImportTrajectory(path, TrajectoryImportOptions()); },
              {path + ":1", "non-finite"});
  // Neither 8 nor 12 numbers: auto cannot tell.
  WriteText(path, "1 2 3\n");
  ExpectError([&] { ImportTrajectory(path, TrajectoryImportOptions()); },
              {path, "cannot tell the trajectory format", "3 numbers", "--vo-format"});
  // A TUM file read as KITTI.
  WriteText(path, "1 0 0 0 0 0 0 1\n");
  TrajectoryImportOptions kitti;
  kitti.format = TrajectoryFileFormat::kKitti;
  ExpectError([&] { ImportTrajectory(path, kitti); }, {path + ":1", "expected 12 numbers"});
  // Empty (comments only) and missing files.
  WriteText(path, "# nothing\n");
  TrajectoryImportOptions tum;
  tum.format = TrajectoryFileFormat::kTum;
  ExpectError([&] { ImportTrajectory(path, tum); }, {path, "no poses"});
  ExpectError([&] { ImportTrajectory(dir / "missing.tum", TrajectoryImportOptions()); },
              {"missing.tum", "cannot open"});
}

TEST(TrajectoryImport, BadKittiInput) {
  TempDir dir;
  const std::string path = dir / "poses.txt";
  // Not a rotation (a scaled one).
  WriteText(path, "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 2 0 0 0 0 2 0\n");
  ExpectError([&] { ImportTrajectory(path, TrajectoryImportOptions()); },
              {path + ":2", "not a rotation matrix"});
  WriteText(path, kKitti);
  // Fewer times than poses.
  WriteText(dir / "times.txt", "0.0\n0.1\n");
  TrajectoryImportOptions options;
  options.times_path = dir / "times.txt";
  ExpectError([&] { ImportTrajectory(path, options); }, {path + ":3", "no timestamp for pose 2"});
  // A number of poses that does not match the drive's frames.
  options = TrajectoryImportOptions();
  options.frame_times = {1.0, 2.0};
  ExpectError([&] { ImportTrajectory(path, options); },
              {path, "3 KITTI poses but the drive has 2 frames", "--vo-times"});
  // A times file for TUM poses; relative times without frame times, or with an offset.
  WriteText(dir / "vo.tum", kTum);
  options = TrajectoryImportOptions();
  options.times_path = dir / "times.txt";
  ExpectError([&] { ImportTrajectory(dir / "vo.tum", options); }, {"KITTI poses only"});
  options = TrajectoryImportOptions();
  options.relative_times = true;
  ExpectError([&] { ImportTrajectory(path, options); }, {"--relative-times needs"});
  options.frame_times = {1.0, 2.0, 3.0};
  options.time_offset_s = 2.0;
  ExpectError([&] { ImportTrajectory(path, options); }, {"not both"});
}

TEST(TrajectoryImport, InterpolatePose) {
  std::vector<StampedPose> poses(3);
  poses[0].timestamp_s = 10.0;
  poses[1].timestamp_s = 11.0;
  poses[1].world_from_cam =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY())),
              Eigen::Vector3d(2, 0, 4));
  poses[2].timestamp_s = 15.0;
  poses[2].world_from_cam.translation = Eigen::Vector3d(10, 0, 0);
  // At a pose, and within 1 ms of one: the pose itself.
  auto p = InterpolatePose(poses, 11.0, 1.0);
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->translation, poses[1].world_from_cam.translation);
  p = InterpolatePose(poses, 11.0009, 1.0);
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->translation, poses[1].world_from_cam.translation);
  p = InterpolatePose(poses, 9.9995, 1.0);  // just before the start, within 1 ms
  ASSERT_TRUE(p.has_value());
  // Between: linear centre, slerp rotation.
  p = InterpolatePose(poses, 10.25, 1.0);
  ASSERT_TRUE(p.has_value());
  EXPECT_LT((p->translation - Eigen::Vector3d(0.5, 0, 1)).norm(), 1e-12);
  EXPECT_NEAR(RotationDifferenceDeg(p->rotation, Eigen::Quaterniond::Identity()),
              0.1 * 180.0 / M_PI, 1e-9);
  // Across a gap larger than max_gap_s, outside the trajectory, or no poses: nothing.
  EXPECT_FALSE(InterpolatePose(poses, 13.0, 1.0).has_value());
  EXPECT_TRUE(InterpolatePose(poses, 13.0, 4.0).has_value());
  EXPECT_FALSE(InterpolatePose(poses, 9.9, 1.0).has_value());
  EXPECT_FALSE(InterpolatePose(poses, 15.1, 10.0).has_value());
  EXPECT_FALSE(InterpolatePose({}, 10.0, 1.0).has_value());
}

}  // namespace
}  // namespace epiloc
