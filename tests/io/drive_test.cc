#include "epiloc/io/drive.h"

#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <gmock/gmock.h>
#include <nlohmann/json.hpp>
#include <opencv2/videoio.hpp>

#include "io_test_util.h"

namespace epiloc {
namespace {

using Json = nlohmann::json;
constexpr int kWidth = 64;
constexpr int kHeight = 48;

Json CameraJson() {
  return {{"width", kWidth},
          {"height", kHeight},
          {"fx", 50.5},
          {"fy", 50.25},
          {"cx", 31.5},
          {"cy", 23.5},
          {"distortion", {-0.1, 0.01, 0.001, -0.002, 0.0}}};
}

// A drive directory: 4 grey PNG frames (unpadded numbers 1, 2, 9, 10) with a timestamps file, GNSS
// as lat/lon CSV, ground truth as NMEA, a LiDAR CSV with one scan.
class DriveDir {
 public:
  DriveDir() {
    for (const int n : {1, 2, 9, 10}) {
      WriteImage(dir_ / fmt::format("images/img_{}.png", n), Pattern(kWidth, kHeight, CV_8UC1, n));
    }
    WriteText(dir_ / "times.txt", "100.0\n100.1\n100.2\n100.3\n");
    WriteText(dir_ / "gnss.csv",
              "timestamp_s,lat_deg,lon_deg,alt_m\n99.0,49.0,8.4,100\n99.5,49.00001,8.4,100\n"
              "100.0,49.00002,8.4,100\n");
    WriteText(dir_ / "truth.nmea",
              "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\n"
              "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\n");
    WriteText(dir_ / "scans/0.bin", "0123456789abcdef");
    WriteText(dir_ / "lidar.csv",
              "scan,timestamp_s,path,format,lat_deg,lon_deg,alt_m,qw,qx,qy,qz\n"
              "0,100.05,scans/0.bin,kitti_bin,49.0,8.4,101.5,1,0,0,0\n");
    manifest_ = {{"epiloc_drive", 1},
                 {"name", "test_drive"},
                 {"camera", CameraJson()},
                 {"frames", {{"folder", "images"}, {"timestamps", "times.txt"}}},
                 {"gnss", {{"file", "gnss.csv"}, {"format", "csv"}}},
                 {"ground_truth", {{"file", "truth.nmea"}, {"format", "nmea"}}},
                 {"lidar", {{"csv", "lidar.csv"}}},
                 {"max_gap_s", 0.75},
                 {"time_offset_s", 0.5}};
    Save();
  }

  Json& manifest() { return manifest_; }
  void Save() { WriteText(dir_ / "drive.json", manifest_.dump(2)); }
  std::string str() const { return dir_.str(); }
  std::string operator/(const std::string& name) const { return dir_ / name; }
  // Saves the manifest and expects LoadDrive to fail with a message containing `parts`.
  void ExpectLoadError(const std::vector<std::string>& parts) {
    Save();
    ExpectError([&] { LoadDrive(dir_.str()); }, parts);
  }

 private:
  TempDir dir_;
  Json manifest_;
};

void ExpectSameDrive(const Drive& a, const Drive& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_TRUE(a.camera == b.camera);
  EXPECT_EQ(a.colour, b.colour);
  EXPECT_EQ(a.video, b.video);
  EXPECT_EQ(a.frames, b.frames);
  EXPECT_EQ(a.gnss.samples, b.gnss.samples);
  ASSERT_EQ(a.ground_truth.has_value(), b.ground_truth.has_value());
  if (a.ground_truth) {
    EXPECT_EQ(a.ground_truth->samples, b.ground_truth->samples);
  }
  EXPECT_EQ(a.lidar, b.lidar);
  EXPECT_EQ(a.max_gap_s, b.max_gap_s);
}

TEST(LoadDrive, FolderWithTimestampsAndAllSources) {
  DriveDir dir;
  const Drive drive = LoadDrive(dir.str());
  EXPECT_EQ(drive.dir, dir.str());
  EXPECT_EQ(drive.name, "test_drive");
  EXPECT_EQ(drive.camera.width, kWidth);
  EXPECT_EQ(drive.camera.fy, 50.25);
  EXPECT_EQ(drive.camera.distortion[3], -0.002);
  EXPECT_FALSE(drive.colour);
  EXPECT_EQ(drive.max_gap_s, 0.75);
  ASSERT_EQ(drive.frames.size(), 4u);
  // Ordered by the number in the name (img_9 before img_10), times by that order.
  const std::vector<frame_t> numbers = {drive.frames[0].frame, drive.frames[1].frame,
                                        drive.frames[2].frame, drive.frames[3].frame};
  EXPECT_EQ(numbers, (std::vector<frame_t>{1, 2, 9, 10}));
  EXPECT_EQ(drive.frames[2].image, "images/img_9.png");
  EXPECT_EQ(drive.frames[3].timestamp_s, 100.3);
  EXPECT_EQ(drive.ImagePath(drive.frames[0]), dir / "images/img_1.png");
  // time_offset_s is added to position times.
  ASSERT_EQ(drive.gnss.samples.size(), 3u);
  EXPECT_EQ(drive.gnss.samples[0].timestamp_s, 99.5);
  ASSERT_TRUE(drive.ground_truth.has_value());
  ASSERT_EQ(drive.ground_truth->samples.size(), 1u);
  EXPECT_DOUBLE_EQ(drive.ground_truth->samples[0].timestamp_s,
                   8847.0 * 86400 + 12 * 3600 + 35 * 60 + 19 + 0.5);
  ASSERT_EQ(drive.lidar.size(), 1u);
  EXPECT_EQ(drive.lidar[0].format, "kitti_bin");
  EXPECT_EQ(drive.ScanPath(drive.lidar[0]), dir / "scans/0.bin");
  EXPECT_EQ(drive.lidar[0].sensor_position.alt_m, 101.5);
}

// Issue 18 item 12: an empty scan file was counted as a scan; a folder named as an image was
// "not found".
TEST(LoadDrive, EmptyScansAndFoldersAsImagesAreNamed) {
  DriveDir dir;
  WriteText(dir / "scans/0.bin", "");
  ExpectError([&] { LoadDrive(dir.str()); }, {"lidar.csv:2", "scans/0.bin", "empty (0 bytes)"});
  WriteText(dir / "scans/0.bin", "0123456789abcdef");
  WriteText(dir / "frames.csv", "frame,timestamp_s,image\n0,100.0,images\n");
  dir.manifest()["frames"] = {{"csv", "frames.csv"}};
  dir.Save();
  ExpectError([&] { LoadDrive(dir.str()); }, {"frames.csv:2", "is a folder, not a file"});
}

TEST(LoadDrive, FolderWithFpsAndUnnumberedNames) {
  DriveDir dir;
  dir.manifest()["frames"] = {{"folder", "images"}, {"fps", 4.0}, {"start_s", 10.0}};
  Drive drive = LoadDrive((dir.Save(), dir.str()));
  ASSERT_EQ(drive.frames.size(), 4u);
  EXPECT_EQ(drive.frames[0].timestamp_s, 10.0);
  EXPECT_EQ(drive.frames[2].timestamp_s,
            12.0);  // frame 9: (9 - 1) / 4 s after the first

  WriteImage(dir / "plain/b.png", Pattern(kWidth, kHeight, CV_8UC1));
  WriteImage(dir / "plain/a.jpg", Pattern(kWidth, kHeight, CV_8UC3));
  WriteText(dir / "plain/notes.txt", "not an image");
  dir.manifest()["frames"] = {{"folder", "plain"}, {"fps", 10.0}};
  drive = LoadDrive((dir.Save(), dir.str()));
  ASSERT_EQ(drive.frames.size(), 2u);
  EXPECT_EQ(drive.frames[0].frame, 0);
  EXPECT_EQ(drive.frames[0].image, "plain/a.jpg");
  EXPECT_EQ(drive.frames[1].frame, 1);
  EXPECT_DOUBLE_EQ(drive.frames[1].timestamp_s, 0.1);
}

TEST(LoadDrive, CsvFramesAndLocalPositions) {
  DriveDir dir;
  WriteText(dir / "frames.csv", "frame,timestamp_s,image\n5,1.0,images/img_1.png\n6,1.0," +
                                    (dir / "images/img_2.png") + "\n8,1.2,images/img_9.png\n");
  WriteText(dir / "local.csv",
            "timestamp_s,x_m,y_m,z_m,qw,qx,qy,qz\n0.5,0,0,0,1,0,0,0\n"
            "1.5,3,4,0,1,0,0,0\n");
  dir.manifest()["frames"] = {{"csv", "frames.csv"}};
  dir.manifest()["gnss"] = {{"file", "local.csv"}};
  dir.manifest()["origin"] = {{"lat_deg", 49.0}, {"lon_deg", 8.4}, {"alt_m", 100.0}};
  dir.manifest().erase("time_offset_s");
  const Drive drive = LoadDrive((dir.Save(), dir.str()));
  ASSERT_EQ(drive.frames.size(), 3u);
  EXPECT_EQ(drive.frames[1].frame, 6);
  EXPECT_EQ(drive.ImagePath(drive.frames[1]), dir / "images/img_2.png");
  ASSERT_EQ(drive.gnss.samples.size(), 2u);
  EXPECT_LT((EnuFrame({49.0, 8.4, 100.0}).ToEnu(drive.gnss.samples[1].position) -
             Eigen::Vector3d(3, 4, 0))
                .norm(),
            1e-6);
  const FramePositions positions = PositionFrames(drive, drive.gnss);
  EXPECT_TRUE(positions.missing.empty());
}

// Writes a 5-frame MJPG video at 10 fps.
void WriteVideo(const std::string& path, int frames) {
  cv::VideoWriter writer(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0,
                         cv::Size(kWidth, kHeight), true);
  ASSERT_TRUE(writer.isOpened()) << path;
  for (int i = 0; i < frames; ++i) writer.write(Pattern(kWidth, kHeight, CV_8UC3, i));
}

TEST(LoadDrive, VideoFrames) {
  DriveDir dir;
  WriteVideo(dir / "drive.avi", 5);
  dir.manifest()["frames"] = {{"video", "drive.avi"}};
  Drive drive = LoadDrive((dir.Save(), dir.str()));
  ASSERT_EQ(drive.frames.size(), 5u);
  EXPECT_EQ(drive.video, "drive.avi");
  EXPECT_EQ(drive.VideoPath(), dir / "drive.avi");
  EXPECT_EQ(drive.frames[4].frame, 4);
  EXPECT_NEAR(drive.frames[4].timestamp_s, 0.4, 1e-6);
  EXPECT_TRUE(drive.frames[0].image.empty());

  WriteText(dir / "video_times.txt", "5\n5.2\n5.3\n5.5\n5.6\n");
  dir.manifest()["frames"] = {{"video", "drive.avi"}, {"timestamps", "video_times.txt"}};
  drive = LoadDrive((dir.Save(), dir.str()));
  ASSERT_EQ(drive.frames.size(), 5u);
  EXPECT_EQ(drive.frames[3].timestamp_s, 5.5);

  dir.manifest()["frames"] = {{"video", "drive.avi"}, {"fps", 20.0}, {"start_s", 1.0}};
  drive = LoadDrive((dir.Save(), dir.str()));
  ASSERT_EQ(drive.frames.size(), 5u);
  EXPECT_DOUBLE_EQ(drive.frames[2].timestamp_s, 1.1);

  // The canonical form of a video drive round-trips.
  TempDir out;
  WriteDrive(drive, out.str());
  Drive expected = drive;
  // Written absolute: the copy lives elsewhere.
  expected.video = dir / "drive.avi";
  expected.lidar[0].path = dir / "scans/0.bin";
  ExpectSameDrive(LoadDrive(out.str()), expected);
}

TEST(WriteDrive, RoundTripInTheSameDirectoryIsExact) {
  DriveDir dir;
  const Drive drive = LoadDrive(dir.str());
  WriteDrive(drive, dir.str());
  const Drive again = LoadDrive(dir.str());
  ExpectSameDrive(drive, again);
  EXPECT_EQ(again.frames[0].image, "images/img_1.png");  // relative paths kept
}

TEST(WriteDrive, RoundTripElsewhereKeepsFullPrecision) {
  DriveDir dir;
  Drive drive = LoadDrive(dir.str());
  // Values that need all 17 digits, an orientation and frame ties.
  drive.camera.fx = 1.0 / 3.0 * 150;
  drive.colour = true;
  drive.frames[1].timestamp_s = 100.1 + 1e-9;
  drive.gnss.samples[1].enu_from_cam =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 3).normalized()));
  drive.gnss.samples[2].frame = 9;
  drive.gnss.samples[0].position.lat_deg = 49.000000123456789;
  drive.lidar[0].enu_from_sensor = *drive.gnss.samples[1].enu_from_cam;
  for (auto& f : drive.frames) f.image = drive.ImagePath(f);  // absolute, as KITTI imports
  for (auto& s : drive.lidar) s.path = drive.ScanPath(s);
  TempDir out;
  WriteDrive(drive, out / "copy");
  const Drive loaded = LoadDrive(out / "copy");
  EXPECT_EQ(loaded.dir, out / "copy");
  ExpectSameDrive(drive, loaded);

  // Relative paths are made absolute when writing elsewhere.
  const Drive relative = LoadDrive(dir.str());
  WriteDrive(relative, out / "moved");
  const Drive moved = LoadDrive(out / "moved");
  EXPECT_EQ(moved.frames[0].image, dir / "images/img_1.png");
  EXPECT_EQ(moved.lidar[0].path, dir / "scans/0.bin");
}

TEST(LoadDrive, RejectsBadManifests) {
  DriveDir dir;
  const std::string file = dir / "drive.json";
  dir.manifest()["framse"] = 1;
  dir.ExpectLoadError({file, "unknown key 'framse'"});
  dir.manifest().erase("framse");
  dir.manifest()["camera"]["fxx"] = 1;
  dir.ExpectLoadError({file, "unknown key 'camera.fxx'"});
  dir.manifest()["camera"] = CameraJson();
  dir.manifest()["camera"].erase("fy");
  dir.ExpectLoadError({file, "missing key 'camera.fy'"});
  dir.manifest()["camera"] = CameraJson();
  dir.manifest()["camera"]["cx"] = 100.0;
  dir.ExpectLoadError({file, "principal point"});
  dir.manifest()["camera"] = CameraJson();
  dir.manifest()["camera"]["distortion"] = {0.1, 0.2};
  dir.ExpectLoadError({file, "camera.distortion"});
  // Issue 18 (leftovers): a distortion that folds over inside the image and non-square pixels.
  dir.manifest()["camera"] = CameraJson();
  dir.manifest()["camera"]["distortion"] = {50.0, -300.0, 0.0, 0.0, 0.0};
  dir.ExpectLoadError({file, "camera: distortion k1=50 k2=-300", "not invertible"});
  dir.manifest()["camera"] = CameraJson();
  dir.manifest()["camera"]["fy"] = 20.0 * dir.manifest()["camera"]["fx"].get<double>();
  dir.ExpectLoadError({file, "camera: fy / fx = 20 "});
  {
    // The same checks on a --calibration file, named in the message.
    const std::string calibration = dir / "calibration.json";
    Json json;
    json["camera"] = CameraJson();
    json["camera"]["distortion"] = {50.0, -300.0, 0.0, 0.0, 0.0};
    std::ofstream(calibration) << json.dump();
    EXPECT_THAT(ErrorOf([&] { ReadCalibrationFile(calibration); }),
                ::testing::HasSubstr(calibration + ": camera: distortion k1=50"));
  }
  dir.manifest()["camera"] = CameraJson();
  dir.manifest()["camera"]["width"] = kWidth + 1;
  dir.ExpectLoadError({dir / "images/img_1.png", "64x48", "65x48"});
  dir.manifest()["camera"] = CameraJson();
  dir.manifest()["epiloc_drive"] = 2;
  dir.ExpectLoadError({file, "version 2"});
  dir.manifest()["epiloc_drive"] = 1;
  dir.manifest()["gnss"]["format"] = "gpx";
  dir.ExpectLoadError({file, "unknown position format 'gpx'"});
  dir.manifest()["gnss"]["format"] = "csv";
  dir.manifest()["frames"] = {{"folder", "images"}};
  dir.ExpectLoadError({file, "\"timestamps\" or \"fps\""});
  dir.manifest()["frames"] = {{"folder", "images"}, {"timestamps", "times.txt"}};
  dir.Save();
  EXPECT_NO_THROW(LoadDrive(dir.str()));

  // Issue 18 (unseen inputs): a key given twice was taken silently (the last one won).
  {
    std::string text = dir.manifest().dump();
    const size_t camera = text.find("\"camera\":{");
    ASSERT_NE(camera, std::string::npos);
    text.insert(camera + 10, "\"fx\":700.0,");
    WriteText(file, text);
    ExpectError([&] { LoadDrive(dir.str()); }, {file, "key 'fx' is given twice"});
    WriteText(file, "{\"name\": \"a\", " + dir.manifest().dump().substr(1));
    ExpectError([&] { LoadDrive(dir.str()); }, {file, "key 'name' is given twice"});
    WriteText(file, "{\"camera\": {\"fx\": 1}, \"frames\": {\"fx\": 1}}");
    ExpectError([&] { LoadDrive(dir.str()); }, {file});  // the same key in two objects is fine
    EXPECT_THAT(ErrorOf([&] { LoadDrive(dir.str()); }), ::testing::Not(::testing::HasSubstr("twice")));
  }
  // Issue 18 (unseen inputs): README's annotated drive.json (// comments) was refused as
  // malformed JSON; comments are accepted, and the values are the same.
  {
    dir.Save();
    const Drive plain = LoadDrive(dir.str());
    const std::vector<std::string> plain_inputs = DriveInputPaths(dir.str());
    ASSERT_GT(plain_inputs.size(), 1u);
    std::string text = dir.manifest().dump(2);
    text.insert(text.find('\n'), "  // format version and name");
    text.insert(text.find("\"camera\""), "/* calibration\n of the frames */ ");
    WriteText(file, text + "\n// the end\n");
    const Drive commented = LoadDrive(dir.str());
    EXPECT_EQ(commented.camera.fx, plain.camera.fx);
    EXPECT_EQ(commented.frames.size(), plain.frames.size());
    EXPECT_EQ(commented.name, plain.name);
    EXPECT_EQ(DriveInputPaths(dir.str()), plain_inputs);  // the output checks see the same inputs
  }
  WriteText(file, "{\"epiloc_drive\": 1,");
  ExpectError([&] { LoadDrive(dir.str()); }, {file, "malformed JSON"});
  WriteText(file, "{\"epiloc_drive\": 1 /* unterminated }");
  ExpectError([&] { LoadDrive(dir.str()); }, {file, "malformed JSON"});
  TempDir empty;
  ExpectError([&] { LoadDrive(empty.str()); }, {empty / "drive.json"});
}

TEST(LoadDrive, RejectsBadFiles) {
  DriveDir dir;
  dir.manifest()["frames"] = {{"csv", "frames.csv"}};
  const std::string frames = dir / "frames.csv";
  WriteText(frames, "frame,timestamp_s,image\n1,1.0,images/img_1.png\n2,1.1,images/nope.png\n");
  dir.ExpectLoadError({frames + ":3", "nope.png"});
  WriteText(frames, "frame,timestamp_s,image\n1,1.0,images/img_1.png\n2,0.9,images/img_2.png\n");
  dir.ExpectLoadError({frames + ":3", "backwards"});
  WriteText(frames, "frame,timestamp_s,image\n1,1.0,images/img_1.png\n1,1.1,images/img_2.png\n");
  dir.ExpectLoadError({frames + ":3", "frame 1 appears twice"});
  WriteText(frames, "frame,timestamp_s,image\n1,1.0\n");
  dir.ExpectLoadError({frames + ":2"});
  WriteText(frames, "frame,timestamp_s,image\n");
  dir.ExpectLoadError({frames, "no frames"});
  WriteText(frames, "frame,timestamp_s,image\n1,1.0,images/img_1.png\n");
  dir.Save();
  EXPECT_NO_THROW(LoadDrive(dir.str()));

  WriteText(dir / "gnss.csv", "timestamp_s,lat_deg,lon_deg,alt_m\n1,49,8,0\n1,49,8,0\n");
  dir.ExpectLoadError({dir / "gnss.csv:3"});
  WriteText(dir / "gnss.csv", "timestamp_s,lat_deg,lon_deg,alt_m\n1,-91,8,0\n");
  dir.ExpectLoadError({dir / "gnss.csv:2", "latitude"});
  WriteText(dir / "gnss.csv", "timestamp_s,lat_deg,lon_deg,alt_m\n1,49,8,0\n");
  WriteText(dir / "truth.nmea",
            "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6B\n");
  dir.ExpectLoadError({dir / "truth.nmea:1", "checksum"});
  dir.manifest().erase("ground_truth");
  WriteText(dir / "lidar.csv",
            "scan,timestamp_s,path,format,lat_deg,lon_deg,alt_m,qw,qx,qy,qz\n"
            "0,100.05,scans/0.bin,las,49.0,8.4,101.5,1,0,0,0\n");
  dir.ExpectLoadError({dir / "lidar.csv:2", "las"});
  WriteText(dir / "lidar.csv",
            "scan,timestamp_s,path,format,lat_deg,lon_deg,alt_m,qw,qx,qy,qz\n"
            "0,100.05,scans/9.bin,kitti_bin,49.0,8.4,101.5,1,0,0,0\n");
  dir.ExpectLoadError({dir / "lidar.csv:2", "9.bin"});
}

TEST(LoadDrive, RejectsBadFolders) {
  DriveDir dir;
  WriteText(dir / "times.txt", "100.0\n100.1\n100.2\n");
  dir.ExpectLoadError({dir / "times.txt", "3 timestamps for 4 images"});
  WriteText(dir / "times.txt", "100.0\n100.1\n100.0\n100.3\n");
  dir.ExpectLoadError({dir / "times.txt:3", "backwards"});
  WriteText(dir / "times.txt", "100.0\n100.1\n100.2\n100.3\n100.4\n");
  WriteImage(dir / "images/frame_0002.png", Pattern(kWidth, kHeight, CV_8UC1));
  dir.ExpectLoadError({dir / "images", "frame number 2"});
  std::filesystem::remove(dir / "images/frame_0002.png");
  WriteText(dir / "images/img_0.png", "not a png");
  dir.ExpectLoadError({dir / "images/img_0.png", "cannot decode"});
  dir.manifest()["frames"] = {{"video", "missing.avi"}};
  dir.ExpectLoadError({dir / "missing.avi"});
}

}  // namespace
}  // namespace epiloc
