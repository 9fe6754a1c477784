// Output paths of the commands, end to end through the binary (issue 18 items 2 and 3): an output
// that is one of the command's inputs is refused with one line naming both and the input is left
// as it was; unwritable outputs are found before the work; nothing partial is left behind.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cli_run_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class OutputPaths : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string data = std::string(EPILOC_SOURCE_DIR) + "/tests/eval/data/";
    fs::copy_file(data + "result.csv", dir_ / "result.csv");
    fs::copy_file(data + "truth.csv", dir_ / "truth.csv");
    WriteText(dir_ / "route.sqlite", "stands for a route database\n");
    // A drive directory: only its manifest is read before the outputs are checked.
    WriteText(dir_ / "drive/drive.json",
              R"({"epiloc_drive": 1, "name": "d", "frames": {"csv": "frames.csv"},
                  "gnss": {"file": "gnss.csv", "format": "csv"}})");
    WriteText(dir_ / "drive/frames.csv", "frame,timestamp_s,image\n");
    WriteText(dir_ / "drive/gnss.csv", "timestamp_s,lat_deg,lon_deg,alt_m\n");
  }

  // Runs the command, expects exit 1 with one line on stderr holding every part, and `input`
  // unchanged.
  void ExpectRefused(const std::string& args,
                     const std::string& input,
                     const std::vector<std::string>& parts) {
    const std::string before = ReadAll(input);
    const CliRun run = RunCli(args);
    EXPECT_EQ(run.exit_code, 1) << args << "\n" << run.err;
    EXPECT_EQ(NumLines(run.err), 1) << run.err;
    for (const std::string& part : parts) EXPECT_THAT(run.err, HasSubstr(part)) << args;
    EXPECT_EQ(ReadAll(input), before) << input << " was changed by: " << args;
  }

  TempDir dir_;
};

TEST_F(OutputPaths, LocalizeRefusesToOverwriteTheDatabaseOrTheDrive) {
  const std::string db = dir_ / "route.sqlite";
  ExpectRefused(fmt::format("localize --db {} --drive {} --out {}", db, dir_ / "drive", db), db,
                {"--out " + db, "input --db " + db});
  // Another spelling of the same file.
  ExpectRefused(
      fmt::format("localize --db {} --drive {} --out {}/drive/../route.sqlite", db,
                  dir_ / "drive", dir_.str()),
      db, {"--out", "input --db"});
  ExpectRefused(fmt::format("localize --db {} --drive {} --out - --geojson {}", db, dir_ / "drive",
                            dir_ / "drive/gnss.csv"),
                dir_ / "drive/gnss.csv", {"--geojson", "input --drive", "gnss.csv"});
  ExpectRefused(fmt::format("localize --db {} --drive {} --out x.csv --diagnostics {}", db,
                            dir_ / "drive", dir_ / "drive/drive.json"),
                dir_ / "drive/drive.json", {"--diagnostics", "drive.json"});
  ExpectRefused(fmt::format("localize --db {} --drive {} --out - --nmea-out {}", db,
                            dir_ / "drive", dir_ / "drive/frames.csv"),
                dir_ / "drive/frames.csv", {"--nmea-out", "frames.csv"});
}

// Issue 18 (unseen inputs): `localize --out <drive>/images/000003.png` overwrote a frame of the
// drive with the result CSV: the images a frames CSV names (and the scans of a LiDAR CSV) are
// inputs too.
TEST_F(OutputPaths, TheImagesAndScansADriveNamesAreInputs) {
  const std::string db = dir_ / "route.sqlite";
  WriteText(dir_ / "drive2/drive.json",
            R"({"epiloc_drive": 1, "name": "d", "frames": {"csv": "frames.csv"},
                "lidar": {"csv": "lidar.csv"}})");
  WriteText(dir_ / "drive2/frames.csv",
            "frame,timestamp_s,image\n0,0,images/000000.png\n1,0.1," + dir_ / "elsewhere.png" +
                "\n");
  WriteText(dir_ / "drive2/images/000000.png", "stands for an image");
  WriteText(dir_ / "elsewhere.png", "stands for another image");
  WriteText(dir_ / "drive2/lidar.csv",
            "scan,timestamp_s,path,format,lat_deg,lon_deg,alt_m,qw,qx,qy,qz\n"
            "0,0,scans/0.bin,kitti_bin,49,8,100,1,0,0,0\n");
  WriteText(dir_ / "drive2/scans/0.bin", "stands for a scan");
  const std::string drive = dir_ / "drive2";
  ExpectRefused(fmt::format("localize --db {} --drive {} --out {}", db, drive,
                            dir_ / "drive2/images/000000.png"),
                dir_ / "drive2/images/000000.png", {"--out", "input --drive", "000000.png"});
  ExpectRefused(fmt::format("localize --db {} --drive {} --out - --diagnostics {}", db, drive,
                            dir_ / "elsewhere.png"),
                dir_ / "elsewhere.png", {"--diagnostics", "input --drive", "elsewhere.png"});
  ExpectRefused(fmt::format("vo --drive {} --out {}", drive, dir_ / "drive2/scans/0.bin"),
                dir_ / "drive2/scans/0.bin", {"--out", "input --drive", "0.bin"});
  // The corrected drive written over the drive itself, or its steps CSV over a scan.
  ExpectRefused(fmt::format("lidar-track --drive {0} --out {0}", drive), dir_ / "drive2/lidar.csv",
                {"--out", "input --drive", "drive2"});
  ExpectRefused(
      fmt::format("lidar-track --drive {} --steps {}", drive, dir_ / "drive2/scans/0.bin"),
      dir_ / "drive2/scans/0.bin", {"--steps", "input --drive", "0.bin"});
}

// Issue 18 (unseen inputs): outputs a command writes besides --out were not checked: `vo --points
// <drive>/frames.csv` overwrote the drive's frames CSV; build-map's origin sidecar <out>.json
// could overwrite an input named so.
TEST_F(OutputPaths, SecondaryOutputsAreCheckedToo) {
  const std::string drive = dir_ / "drive";
  ExpectRefused(fmt::format("vo --drive {} --out {} --points {}", drive, dir_ / "vo.tum",
                            dir_ / "drive/frames.csv"),
                dir_ / "drive/frames.csv", {"--points", "input --drive", "frames.csv"});
  EXPECT_FALSE(fs::exists(dir_ / "vo.tum"));
  WriteText(dir_ / "map.ply.json", "{}");
  fs::rename(dir_ / "drive/drive.json", dir_ / "drive/manifest.json");
  fs::create_symlink("../map.ply.json", dir_ / "drive/drive.json");
  WriteText(dir_ / "map.ply.json", ReadAll(dir_ / "drive/manifest.json"));
  ExpectRefused(fmt::format("build-map --drive {} --out {}", drive, dir_ / "map.ply"),
                dir_ / "map.ply.json", {"--out (sidecar)", "map.ply.json", "input --drive"});
}

TEST_F(OutputPaths, ExportEvaluateGeorefBuildDbRefuseTheirInputs) {
  const std::string result = dir_ / "result.csv";
  ExpectRefused(fmt::format("export --result {0} --format geojson --out {0}", result), result,
                {"--out", "input --result"});
  ExpectRefused(fmt::format("evaluate --result {0} --truth {1} --json {0}", result,
                            dir_ / "truth.csv"),
                result, {"--json", "input --result"});
  ExpectRefused(fmt::format("evaluate --result {0} --truth {1} --report {1}", result,
                            dir_ / "truth.csv"),
                dir_ / "truth.csv", {"--report", "input --truth"});
  ExpectRefused(fmt::format("georef --vo {0} --anchors {1} --out {1}", dir_ / "truth.csv", result),
                result, {"--out", "input --anchors"});
  ExpectRefused(fmt::format("build-db --drive {} --db {}", dir_ / "drive", dir_ / "drive/frames.csv"),
                dir_ / "drive/frames.csv", {"--db", "input --drive"});
  ExpectRefused(fmt::format("build-db --drive {} --db {} --positions {}", dir_ / "drive",
                            dir_ / "result.csv", dir_ / "result.csv"),
                result, {"--db", "input --positions"});
}

TEST_F(OutputPaths, UnwritableOutputIsFoundBeforeTheWork) {
  // Before: localize ran the whole drive, wrote --out, then failed on --geojson.
  const CliRun run = RunCli(fmt::format("localize --db {} --drive {} --out {} --geojson {}",
                                        dir_ / "route.sqlite", dir_ / "drive", dir_ / "out.csv",
                                        dir_ / "missing/out.geojson"));
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_EQ(NumLines(run.err), 1) << run.err;
  EXPECT_THAT(run.err, HasSubstr("--geojson"));
  EXPECT_THAT(run.err, HasSubstr("does not exist"));
  EXPECT_FALSE(fs::exists(dir_ / "out.csv"));

  const CliRun folder = RunCli(fmt::format("export --result {} --format gpx --out {}",
                                           dir_ / "result.csv", dir_ / "drive"));
  EXPECT_EQ(folder.exit_code, 1);
  EXPECT_THAT(folder.err, HasSubstr("is a folder"));
}

TEST_F(OutputPaths, AFailedExportLeavesThePreviousFileAndNoTemporaries) {
  WriteText(dir_ / "out.gpx", "previous\n");
  WriteText(dir_ / "bad.csv", "frame,timestamp_s,lat_deg,lon_deg,alt_m,s_m,db_frame,method,status\n"
                              "0,0,49,8,100,0,0,gps,ok\n1,1,91,8,100,0,0,gps,ok\n");
  const CliRun run =
      RunCli(fmt::format("export --result {} --format gpx --out {}", dir_ / "bad.csv", dir_ / "out.gpx"));
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_EQ(ReadAll(dir_ / "out.gpx"), "previous\n");
  const CliRun ok = RunCli(
      fmt::format("export --result {} --format gpx --out {}", dir_ / "result.csv", dir_ / "out.gpx"));
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_THAT(ReadAll(dir_ / "out.gpx"), HasSubstr("<gpx"));
  for (const auto& entry : fs::directory_iterator(dir_.str())) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
  }
}

// Issue 18 (leftovers): `vo` on a drive where no frame can be posed (featureless frames) exited
// 0 with an empty trajectory.
TEST_F(OutputPaths, VoThatPosesNothingFailsAndWritesNothing) {
  const std::string drive = dir_ / "blank";
  std::string frames = "frame,timestamp_s,image\n";
  for (int i = 0; i < 8; ++i) {
    // A uniform grey 64x48 PGM: nothing to track.
    WriteText(drive + fmt::format("/images/{}.pgm", i),
              "P5\n64 48\n255\n" + std::string(64 * 48, static_cast<char>(128)));
    frames += fmt::format("{},{:.1f},images/{}.pgm\n", i, 0.1 * i, i);
  }
  WriteText(drive + "/frames.csv", frames);
  WriteText(drive + "/drive.json",
            R"({"epiloc_drive": 1, "name": "blank", "frames": {"csv": "frames.csv"},
                "camera": {"width": 64, "height": 48, "fx": 60, "fy": 60, "cx": 32, "cy": 24}})");
  const CliRun run = RunCli(fmt::format("vo --quiet --drive {} --out {}", drive, dir_ / "vo.tum"));
  EXPECT_EQ(run.exit_code, 1) << run.err;
  EXPECT_EQ(NumLines(run.err), 1) << run.err;
  EXPECT_THAT(run.err, HasSubstr("blank"));
  EXPECT_THAT(run.err, HasSubstr("0 of 8 frames could be posed"));
  EXPECT_FALSE(fs::exists(dir_ / "vo.tum"));
  EXPECT_FALSE(fs::exists(dir_ / "vo.points.csv"));
}

// Issue 18 (leftovers): `import-kitti --out` inside the raw KITTI folder wrote into the (read-only
// shared) input data. Refused before anything is written, symbolic links resolved; the folder
// with the calibration files (the raw drive's parent) is an input folder too.
TEST_F(OutputPaths, ImportKittiRefusesAnOutputInsideTheInput) {
  const std::string calib = dir_ / "kitti/2011_09_26";
  const std::string raw = calib + "/2011_09_26_drive_0001_sync";
  fs::create_directories(raw + "/image_00/data");
  fs::create_directory_symlink(raw, dir_ / "link");
  for (const std::string& out : {raw, raw + "/", raw + "/imported", raw + "/image_00/../imported",
                                 dir_ / "link/imported", calib + "/imported"}) {
    SCOPED_TRACE(out);
    const CliRun run = RunCli(fmt::format("import-kitti --quiet --raw {} --out {}", raw, out));
    EXPECT_EQ(run.exit_code, 1) << run.err;
    EXPECT_EQ(NumLines(run.err), 1) << run.err;
    EXPECT_THAT(run.err, HasSubstr("inside the KITTI input folder"));
    EXPECT_FALSE(fs::exists(raw + "/imported"));
    EXPECT_FALSE(fs::exists(calib + "/imported"));
  }
  // Elsewhere the import goes on (and here fails on the missing calibration, not on --out).
  const CliRun elsewhere =
      RunCli(fmt::format("import-kitti --quiet --raw {} --out {}", raw, dir_ / "imported"));
  EXPECT_EQ(elsewhere.exit_code, 1);
  EXPECT_THAT(elsewhere.err, HasSubstr("calib_cam_to_cam.txt"));

  // With the real KITTI drive (a copy of its tree made of links, so nothing can reach the shared
  // data): the import wrote its drive inside the raw folder.
  const std::string shared = KittiRawDrive().parent_path().string();
  if (!fs::is_directory(shared + "/2011_09_26_drive_0005_sync")) {
    GTEST_SKIP() << shared << " is absent";
  }
  const std::string kitti = dir_ / "real/2011_09_26";
  const std::string drive = kitti + "/2011_09_26_drive_0005_sync";
  fs::create_directories(drive);
  for (const char* file :
       {"calib_cam_to_cam.txt", "calib_imu_to_velo.txt", "calib_velo_to_cam.txt"}) {
    fs::copy_file(shared + "/" + file, kitti + "/" + file);
  }
  for (const auto& entry : fs::directory_iterator(shared + "/2011_09_26_drive_0005_sync")) {
    fs::create_directory_symlink(entry.path(), drive + "/" + entry.path().filename().string());
  }
  const CliRun inside = RunCli(fmt::format("import-kitti --quiet --raw {} --frames 0:4 --out {}",
                                           drive, drive + "/imported"));
  EXPECT_EQ(inside.exit_code, 1) << inside.err;
  EXPECT_THAT(inside.err, HasSubstr("inside the KITTI input folder"));
  EXPECT_FALSE(fs::exists(drive + "/imported"));
  const CliRun outside = RunCli(fmt::format("import-kitti --quiet --raw {} --frames 0:4 --out {}",
                                            drive, dir_ / "real_imported"));
  EXPECT_EQ(outside.exit_code, 0) << outside.err;
  EXPECT_TRUE(fs::exists(dir_ / "real_imported/drive.json"));
}

}  // namespace
}  // namespace epiloc
