#include "epiloc/db/database.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

#include "epiloc/core/error.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A fresh directory per test, removed afterwards.
class DatabaseFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           fmt::format("epiloc_db_test_{}_{}_{}", getpid(),
                       info->test_suite_name(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string PathOf(const std::string& name) const {
    return (dir_ / name).string();
  }

  fs::path dir_;
};

// A raw SQLite connection, independent of the code under test.
class RawConnection {
 public:
  explicit RawConnection(const std::string& path) {
    if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) {
      throw std::runtime_error("cannot open " + path);
    }
  }
  ~RawConnection() { sqlite3_close(db_); }
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;

  void Exec(const std::string& sql) {
    char* message = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &message) !=
        SQLITE_OK) {
      const std::string text = message != nullptr ? message : "?";
      sqlite3_free(message);
      throw std::runtime_error(sql + ": " + text);
    }
  }
  std::string QueryText(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) {
      throw std::runtime_error(sql + ": " + sqlite3_errmsg(db_));
    }
    std::string value;
    if (sqlite3_step(stmt) == SQLITE_ROW &&
        sqlite3_column_text(stmt, 0) != nullptr) {
      value = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
    }
    sqlite3_finalize(stmt);
    return value;
  }
  int64_t QueryInt(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) {
      throw std::runtime_error(sql + ": " + sqlite3_errmsg(db_));
    }
    const int64_t value =
        sqlite3_step(stmt) == SQLITE_ROW ? sqlite3_column_int64(stmt, 0) : -1;
    sqlite3_finalize(stmt);
    return value;
  }

 private:
  sqlite3* db_ = nullptr;
};

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The migration files as they are in the source tree, in order.
std::vector<fs::path> MigrationFiles() {
  const fs::path dir = fs::path(EPILOC_SOURCE_DIR) / "db_schema";
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 9 && std::isdigit(static_cast<unsigned char>(name[0])) &&
        entry.path().extension() == ".sql") {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}


Camera KittiCamera() {
  Camera camera;
  camera.width = 1392;
  camera.height = 512;
  camera.fx = 984.2439;
  camera.fy = 980.8141;
  camera.cx = 690.0;
  camera.cy = 233.1966;
  camera.distortion = {-0.3728755, 0.2037299, 0.002219027, 0.001383707,
                       -0.07233722};
  return camera;
}

FeatureKeypoints RandomKeypoints(int n, std::mt19937* rng) {
  std::uniform_real_distribution<float> uniform(-1000.0f, 1000.0f);
  FeatureKeypoints keypoints(n, 4);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < 4; ++j) keypoints(i, j) = uniform(*rng);
  }
  return keypoints;
}

FeatureDescriptors RandomDescriptors(int n, std::mt19937* rng) {
  std::uniform_int_distribution<int> byte(0, 255);
  FeatureDescriptors descriptors(n, 128);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < 128; ++j)
      descriptors(i, j) = static_cast<uint8_t>(byte(*rng));
  }
  return descriptors;
}

struct SampleFrame {
  DbFrame frame;
  FeatureKeypoints keypoints;
  FeatureDescriptors descriptors;
};

// Everything written by WriteSample, with the ids the database gave.
struct Sample {
  DbCamera camera;
  DbDrive drive;
  std::vector<SampleFrame> frames;
  std::vector<Eigen::Vector3d> route;
  Geodetic origin;
};

Sample WriteSample(Database* db, uint32_t seed) {
  std::mt19937 rng(seed);
  Sample sample;
  sample.origin = {49.0114951367, 8.4167324537, 112.83};
  db->SetEnuOrigin(sample.origin);
  db->SetMeta("created_by", "epiloc test, \"quoted\"; with ; semicolons");

  sample.camera.original = KittiCamera();
  sample.camera.camera = KittiCamera();
  sample.camera.camera.distortion.fill(0.0);
  sample.camera.camera.fx = 800.5;
  sample.camera.camera_id = db->WriteCamera(sample.camera);

  sample.drive.name = "2011_09_26_drive_0001_sync";
  sample.drive.source_dir = "/data/kitti/2011_09_26/2011_09_26_drive_0001_sync";
  sample.drive.camera_id = sample.camera.camera_id;
  sample.drive.positions = "ground_truth";
  sample.drive.num_frames_planned = 3;
  sample.drive.complete = false;
  sample.drive.drive_id = db->WriteDrive(sample.drive);

  const EnuFrame enu(sample.origin);
  const int feature_counts[] = {7, 0, 300};
  for (int i = 0; i < 3; ++i) {
    SampleFrame f;
    f.frame.drive_id = sample.drive.drive_id;
    f.frame.frame = 10 + i;
    f.frame.timestamp_s = 1317.25 + 0.1 * i;
    f.frame.image_path =
        fmt::format("/data/image_00/data/{:010d}.png", f.frame.frame);
    f.frame.image_hash = fmt::format("{:032x}", 1234567 + i);
    f.frame.position = {49.0114951367 + 1e-5 * i, 8.4167324537 + 2e-5 * i,
                        112.83 + 0.01 * i};
    f.frame.center_in_enu = enu.ToEnu(f.frame.position);
    f.frame.heading_deg = 359.5 - i;
    f.frame.s_m = 1.25 * i;
    if (i != 1) {
      f.frame.enu_from_cam = Eigen::Quaterniond(
          Eigen::AngleAxisd(0.3 + i, Eigen::Vector3d(1, 2, 3).normalized()));
    }
    f.keypoints = RandomKeypoints(feature_counts[i], &rng);
    f.descriptors = RandomDescriptors(feature_counts[i], &rng);
    f.frame.num_features = feature_counts[i];
    f.frame.image_id = db->WriteFrame(f.frame, f.keypoints, f.descriptors);
    sample.frames.push_back(f);
  }
  sample.drive.complete = true;
  db->UpdateDrive(sample.drive);

  sample.route = {{0.0, 0.0, 0.0}, {1.5, 2.25, -0.125}, {-3.0, 1e6, 12.0}};
  db->WriteRoute(sample.route);
  return sample;
}

void ExpectFrameEq(const DbFrame& expected, const DbFrame& actual) {
  EXPECT_EQ(expected.image_id, actual.image_id);
  EXPECT_EQ(expected.drive_id, actual.drive_id);
  EXPECT_EQ(expected.frame, actual.frame);
  EXPECT_EQ(expected.timestamp_s, actual.timestamp_s);
  EXPECT_EQ(expected.image_path, actual.image_path);
  EXPECT_EQ(expected.image_hash, actual.image_hash);
  EXPECT_EQ(expected.position.lat_deg, actual.position.lat_deg);
  EXPECT_EQ(expected.position.lon_deg, actual.position.lon_deg);
  EXPECT_EQ(expected.position.alt_m, actual.position.alt_m);
  EXPECT_EQ(expected.center_in_enu, actual.center_in_enu);
  EXPECT_EQ(expected.heading_deg, actual.heading_deg);
  EXPECT_EQ(expected.s_m, actual.s_m);
  ASSERT_EQ(expected.enu_from_cam.has_value(), actual.enu_from_cam.has_value());
  if (expected.enu_from_cam) {
    EXPECT_TRUE(expected.enu_from_cam->isApprox(*actual.enu_from_cam, 1e-15));
  }
  EXPECT_EQ(expected.num_features, actual.num_features);
}

void ExpectSample(const Sample& sample, const Database& db) {
  EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
  EXPECT_EQ(db.GetMeta("created_by"),
            "epiloc test, \"quoted\"; with ; semicolons");
  EXPECT_FALSE(db.GetMeta("no such key").has_value());

  const auto origin = db.EnuOrigin();
  ASSERT_TRUE(origin.has_value());
  EXPECT_EQ(origin->lat_deg, sample.origin.lat_deg);
  EXPECT_EQ(origin->lon_deg, sample.origin.lon_deg);
  EXPECT_EQ(origin->alt_m, sample.origin.alt_m);

  const DbCamera camera = db.ReadCamera(sample.camera.camera_id);
  EXPECT_EQ(camera.camera_id, sample.camera.camera_id);
  EXPECT_EQ(camera.camera, sample.camera.camera);
  EXPECT_EQ(camera.original, sample.camera.original);

  const auto drives = db.ReadDrives();
  ASSERT_EQ(drives.size(), 1u);
  const auto found = db.FindDrive(sample.drive.name);
  ASSERT_TRUE(found.has_value());
  for (const DbDrive& drive : {drives[0], *found}) {
    EXPECT_EQ(drive.drive_id, sample.drive.drive_id);
    EXPECT_EQ(drive.name, sample.drive.name);
    EXPECT_EQ(drive.source_dir, sample.drive.source_dir);
    EXPECT_EQ(drive.camera_id, sample.drive.camera_id);
    EXPECT_EQ(drive.positions, sample.drive.positions);
    EXPECT_EQ(drive.num_frames_planned, sample.drive.num_frames_planned);
    EXPECT_EQ(drive.complete, sample.drive.complete);
  }
  EXPECT_FALSE(db.FindDrive("no such drive").has_value());

  EXPECT_EQ(db.NumFrames(), 3);
  EXPECT_EQ(db.NumFrames(sample.drive.drive_id), 3);
  EXPECT_EQ(db.NumFrames(sample.drive.drive_id + 1), 0);
  EXPECT_EQ(db.NumFeatures(), 307);
  const auto frames = db.ReadFrames();
  const auto drive_frames = db.ReadFrames(sample.drive.drive_id);
  ASSERT_EQ(frames.size(), sample.frames.size());
  ASSERT_EQ(drive_frames.size(), sample.frames.size());
  for (size_t i = 0; i < sample.frames.size(); ++i) {
    const SampleFrame& expected = sample.frames[i];
    SCOPED_TRACE(fmt::format("frame {}", expected.frame.frame));
    EXPECT_TRUE(db.HasFrame(expected.frame.drive_id, expected.frame.frame));
    ExpectFrameEq(expected.frame, frames[i]);
    ExpectFrameEq(expected.frame, drive_frames[i]);
    ExpectFrameEq(expected.frame, db.ReadFrame(expected.frame.image_id));
    const FeatureKeypoints keypoints =
        db.ReadKeypoints(expected.frame.image_id);
    const FeatureDescriptors descriptors =
        db.ReadDescriptors(expected.frame.image_id);
    EXPECT_EQ(keypoints.rows(), expected.keypoints.rows());
    EXPECT_EQ(descriptors.rows(), expected.descriptors.rows());
    EXPECT_TRUE(keypoints == expected.keypoints);
    EXPECT_TRUE(descriptors == expected.descriptors);
  }
  EXPECT_FALSE(db.HasFrame(sample.drive.drive_id, 9));
  EXPECT_EQ(db.ReadRoute(), sample.route);
}

TEST(Database, LatestSchemaVersionMatchesTheMigrationFiles) {
  const auto files = MigrationFiles();
  ASSERT_FALSE(files.empty());
  EXPECT_EQ(Database::LatestSchemaVersion(), static_cast<int>(files.size()));
  EXPECT_EQ(files.front().filename().string().substr(0, 5), "0001_");
}

TEST(Database, RoundTripInMemory) {
  Database db(":memory:");
  EXPECT_EQ(db.path(), ":memory:");
  EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
  EXPECT_FALSE(db.EnuOrigin().has_value());
  EXPECT_TRUE(db.ReadDrives().empty());
  EXPECT_TRUE(db.ReadRoute().empty());
  EXPECT_EQ(db.NumFrames(), 0);
  EXPECT_EQ(db.NumFeatures(), 0);
  const Sample sample = WriteSample(&db, 1);
  ExpectSample(sample, db);
}

TEST_F(DatabaseFileTest, RoundTripOnFileAndReopen) {
  const std::string path = PathOf("route.db");
  Sample sample;
  {
    Database db(path);
    sample = WriteSample(&db, 2);
    ExpectSample(sample, db);
  }
  {
    Database db(path);
    ExpectSample(sample, db);
  }
  Database db(path, Database::Mode::kReadOnly);
  ExpectSample(sample, db);
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"),
            Database::LatestSchemaVersion());
}

TEST(Database, KeypointBlobsKeepEveryFloatBitPattern) {
  Database db(":memory:");
  DbDrive drive;
  drive.name = "d";
  const drive_t drive_id = db.WriteDrive(drive);
  FeatureKeypoints keypoints(3, 4);
  keypoints << 0.0f, -0.0f, 1.0f, -1.5f,  //
      std::numeric_limits<float>::denorm_min(),
      std::numeric_limits<float>::max(),                  //
      std::numeric_limits<float>::lowest(), 3.14159265f,  //
      1391.5f, 511.49f, 1e-20f, 6.2831853f;
  FeatureDescriptors descriptors(3, 128);
  for (int j = 0; j < 128; ++j) {
    descriptors(0, j) = static_cast<uint8_t>(j);
    descriptors(1, j) = static_cast<uint8_t>(255 - j);
    descriptors(2, j) = static_cast<uint8_t>(2 * j);
  }
  DbFrame frame;
  frame.drive_id = drive_id;
  frame.frame = 0;
  const image_t image_id = db.WriteFrame(frame, keypoints, descriptors);
  const FeatureKeypoints read = db.ReadKeypoints(image_id);
  ASSERT_EQ(read.rows(), 3);
  EXPECT_EQ(std::memcmp(read.data(), keypoints.data(), sizeof(float) * 12), 0);
  EXPECT_TRUE(db.ReadDescriptors(image_id) == descriptors);
  EXPECT_EQ(db.ReadFrame(image_id).num_features, 3);
  EXPECT_FALSE(db.ReadFrame(image_id).enu_from_cam.has_value());

  frame.frame = 1;
  const image_t empty_id =
      db.WriteFrame(frame, FeatureKeypoints(0, 4), FeatureDescriptors(0, 128));
  EXPECT_EQ(db.ReadKeypoints(empty_id).rows(), 0);
  EXPECT_EQ(db.ReadDescriptors(empty_id).rows(), 0);
  EXPECT_EQ(db.ReadFrame(empty_id).num_features, 0);
  EXPECT_EQ(db.NumFeatures(), 3);
}

TEST_F(DatabaseFileTest, BlobLayoutIsRowMajorLittleEndian) {
  const std::string path = PathOf("layout.db");
  {
    Database db(path);
    DbDrive drive;
    drive.name = "d";
    DbFrame frame;
    frame.drive_id = db.WriteDrive(drive);
    frame.frame = 0;
    FeatureKeypoints keypoints(2, 4);
    keypoints << 1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f, 8.0f;
    FeatureDescriptors descriptors = FeatureDescriptors::Zero(2, 128);
    descriptors(0, 1) = 7;
    descriptors(1, 0) = 9;
    db.WriteFrame(frame, keypoints, descriptors);
  }
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("SELECT rows FROM keypoints"), 2);
  EXPECT_EQ(raw.QueryInt("SELECT cols FROM keypoints"), 4);
  EXPECT_EQ(raw.QueryInt("SELECT length(data) FROM keypoints"), 32);
  // 2.0f is 0x40000000, stored little-endian as 00 00 00 40 at bytes 4..7 (row
  // 0, column 1).
  EXPECT_EQ(raw.QueryInt(
                "SELECT hex(substr(data, 5, 4)) = '00000040' FROM keypoints"),
            1);
  // 5.0f (0x40a00000) starts row 1 at byte 16.
  EXPECT_EQ(raw.QueryInt(
                "SELECT hex(substr(data, 17, 4)) = '0000A040' FROM keypoints"),
            1);
  EXPECT_EQ(raw.QueryInt("SELECT length(data) FROM descriptors"), 256);
  EXPECT_EQ(
      raw.QueryInt("SELECT hex(substr(data, 2, 1)) = '07' FROM descriptors"),
      1);
  EXPECT_EQ(
      raw.QueryInt("SELECT hex(substr(data, 129, 1)) = '09' FROM descriptors"),
      1);
}

TEST_F(DatabaseFileTest, CorruptBlobsAreDetected) {
  const std::string path = PathOf("corrupt.db");
  image_t image_id = kInvalidImage;
  {
    Database db(path);
    std::mt19937 rng(3);
    DbDrive drive;
    drive.name = "d";
    DbFrame frame;
    frame.drive_id = db.WriteDrive(drive);
    frame.frame = 0;
    image_id = db.WriteFrame(frame, RandomKeypoints(5, &rng),
                             RandomDescriptors(5, &rng));
  }
  const std::string image = fmt::format("image {}", image_id);
  {
    RawConnection raw(path);
    // The schema's CHECKs stop this; a damaged file or another tool need not
    // obey them.
    EXPECT_THROW(raw.Exec("UPDATE keypoints SET data = substr(data, 1, 79)"),
                 std::runtime_error);
    raw.Exec("PRAGMA ignore_check_constraints = ON");
    raw.Exec("UPDATE keypoints SET data = substr(data, 1, 79)");
    raw.Exec("UPDATE descriptors SET rows = 6");
  }
  {
    Database db(path, Database::Mode::kReadOnly);
    ExpectError([&] { db.ReadKeypoints(image_id); },
                {path, "corrupt keypoints blob for " + image});
    ExpectError([&] { db.ReadDescriptors(image_id); },
                {path, "corrupt descriptors blob for " + image});
  }
  {
    RawConnection raw(path);
    raw.Exec("PRAGMA ignore_check_constraints = ON");
    raw.Exec("UPDATE keypoints SET data = zeroblob(100), cols = 5");
    raw.Exec("UPDATE descriptors SET rows = -1, data = zeroblob(0)");
  }
  Database db(path);
  ExpectError([&] { db.ReadKeypoints(image_id); },
              {path, "corrupt keypoints blob for " + image});
  ExpectError([&] { db.ReadDescriptors(image_id); },
              {path, "corrupt descriptors blob for " + image});
  ExpectError([&] { db.ReadKeypoints(image_id + 1); },
              {path, "no keypoints for image"});
}

TEST(Database, DuplicateFrameIsRejected) {
  std::mt19937 rng(4);
  Database db(":memory:");
  DbDrive drive;
  drive.name = "d";
  DbFrame frame;
  frame.drive_id = db.WriteDrive(drive);
  frame.frame = 42;
  db.WriteFrame(frame, RandomKeypoints(3, &rng), RandomDescriptors(3, &rng));
  ExpectError(
      [&] {
        db.WriteFrame(frame, RandomKeypoints(2, &rng),
                      RandomDescriptors(2, &rng));
      },
      {":memory:", "frame 42"});
  EXPECT_EQ(db.NumFrames(), 1);
  EXPECT_EQ(db.NumFeatures(), 3);
  // The same frame number in another drive is fine.
  drive.name = "e";
  frame.drive_id = db.WriteDrive(drive);
  db.WriteFrame(frame, RandomKeypoints(2, &rng), RandomDescriptors(2, &rng));
  EXPECT_EQ(db.NumFrames(), 2);
  // So is a duplicate drive name not.
  ExpectError([&] { db.WriteDrive(drive); }, {":memory:", "UNIQUE"});
}

TEST(Database, InvalidWritesAreRejectedWithoutTrace) {
  std::mt19937 rng(5);
  Database db(":memory:");
  DbDrive drive;
  drive.name = "d";
  DbFrame frame;
  frame.drive_id = db.WriteDrive(drive);
  ExpectError(
      [&] {
        db.WriteFrame(frame, RandomKeypoints(1, &rng),
                      RandomDescriptors(1, &rng));
      },
      {"frame -1 of drive", "must not be negative"});
  frame.frame = 0;
  ExpectError(
      [&] {
        db.WriteFrame(frame, RandomKeypoints(3, &rng),
                      RandomDescriptors(2, &rng));
      },
      {"3 keypoints but 2 descriptors"});
  DbFrame bad = frame;
  bad.position.lat_deg = 91.0;
  ExpectError(
      [&] {
        db.WriteFrame(bad, RandomKeypoints(1, &rng),
                      RandomDescriptors(1, &rng));
      },
      {"latitude 91"});
  bad = frame;
  bad.heading_deg = 360.0;
  ExpectError(
      [&] {
        db.WriteFrame(bad, RandomKeypoints(1, &rng),
                      RandomDescriptors(1, &rng));
      },
      {"heading"});
  bad = frame;
  bad.s_m = std::nan("");
  ExpectError(
      [&] {
        db.WriteFrame(bad, RandomKeypoints(1, &rng),
                      RandomDescriptors(1, &rng));
      },
      {"finite"});
  // A frame of a drive that does not exist fails on the foreign key, leaving no
  // features behind.
  bad = frame;
  bad.drive_id = 999;
  ExpectError(
      [&] {
        db.WriteFrame(bad, RandomKeypoints(1, &rng),
                      RandomDescriptors(1, &rng));
      },
      {"FOREIGN KEY"});
  EXPECT_EQ(db.NumFrames(), 0);

  DbCamera camera;
  camera.camera = KittiCamera();
  camera.original = KittiCamera();
  camera.original.fx = -1.0;
  ExpectError([&] { db.WriteCamera(camera); }, {"original camera", "focal"});
  ExpectError([&] { db.ReadCamera(7); }, {"no camera 7"});
  ExpectError([&] { db.ReadFrame(7); }, {"no image 7"});
  DbDrive missing;
  missing.drive_id = 77;
  missing.name = "x";
  ExpectError([&] { db.UpdateDrive(missing); }, {"no drive 77"});
  DbDrive unknown_camera;
  unknown_camera.name = "u";
  unknown_camera.camera_id = 5;
  ExpectError([&] { db.WriteDrive(unknown_camera); }, {"FOREIGN KEY"});
}

TEST(Database, FramesAreOrderedByDriveThenTime) {
  Database db(":memory:");
  DbDrive drive;
  drive.name = "b";
  const drive_t second = db.WriteDrive(drive);
  drive.name = "a";
  const drive_t first = db.WriteDrive(drive);
  ASSERT_LT(second, first);
  const double times[] = {3.0, 1.0, 2.0};
  for (int i = 0; i < 3; ++i) {
    for (const drive_t id : {first, second}) {
      DbFrame frame;
      frame.drive_id = id;
      frame.frame = i;
      frame.timestamp_s = times[i];
      db.WriteFrame(frame, FeatureKeypoints(0, 4), FeatureDescriptors(0, 128));
    }
  }
  const auto frames = db.ReadFrames();
  ASSERT_EQ(frames.size(), 6u);
  const std::vector<std::pair<drive_t, frame_t>> expected = {
      {second, 1}, {second, 2}, {second, 0},
      {first, 1},  {first, 2},  {first, 0}};
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].drive_id, expected[i].first) << i;
    EXPECT_EQ(frames[i].frame, expected[i].second) << i;
  }
  const auto first_frames = db.ReadFrames(first);
  ASSERT_EQ(first_frames.size(), 3u);
  EXPECT_EQ(first_frames[0].timestamp_s, 1.0);
  EXPECT_EQ(first_frames[2].timestamp_s, 3.0);
}

TEST(Database, EnuOriginIsSetOnce) {
  Database db(":memory:");
  const Geodetic origin{-33.8688197, 151.2092955, 58.123456789012345};
  db.SetEnuOrigin(origin);
  db.SetEnuOrigin(origin);  // the same again is fine
  ExpectError(
      [&] {
        db.SetEnuOrigin({-33.8688197, 151.2092956, 58.0});
      },
      {"ENU origin is already"});
  ExpectError([&] { db.SetEnuOrigin({95.0, 0.0, 0.0}); }, {"latitude 95"});
  const auto read = db.EnuOrigin();
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->lat_deg, origin.lat_deg);
  EXPECT_EQ(read->lon_deg, origin.lon_deg);
  EXPECT_EQ(read->alt_m, origin.alt_m);
  EXPECT_EQ(db.GetMeta("enu_origin_lat_deg"), "-33.8688197");
}

TEST(Database, RouteIsReplacedAsAWhole) {
  Database db(":memory:");
  db.WriteRoute({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}});
  db.WriteRoute({{5, 5, 5}, {6, 6, 6}});
  const std::vector<Eigen::Vector3d> expected = {{5, 5, 5}, {6, 6, 6}};
  EXPECT_EQ(db.ReadRoute(), expected);
  ExpectError(
      [&] {
        db.WriteRoute(
            {{0, 0, 0}, {std::numeric_limits<double>::infinity(), 0, 0}});
      },
      {"route point is not finite"});
  EXPECT_EQ(db.ReadRoute(), expected);
}

// Not an epiloc::Error, so an unexpected failure inside the unit of work is not
// mistaken for it.
struct UnitOfWorkFailed {};

TEST(Database, TransactionRollsBackOnException) {
  std::mt19937 rng(6);
  Database db(":memory:");
  db.SetMeta("state", "before");
  try {
    Database::Transaction transaction(db);
    DbDrive drive;
    drive.name = "d";
    DbFrame frame;
    frame.drive_id = db.WriteDrive(drive);
    frame.frame = 0;
    db.WriteFrame(frame, RandomKeypoints(4, &rng), RandomDescriptors(4, &rng));
    db.SetMeta("state", "during");
    db.WriteRoute({{0, 0, 0}, {1, 1, 1}});
    EXPECT_EQ(db.NumFrames(), 1);
    throw UnitOfWorkFailed();
  } catch (const UnitOfWorkFailed&) {
  }
  EXPECT_EQ(db.NumFrames(), 0);
  EXPECT_EQ(db.NumFeatures(), 0);
  EXPECT_TRUE(db.ReadDrives().empty());
  EXPECT_TRUE(db.ReadRoute().empty());
  EXPECT_EQ(db.GetMeta("state"), "before");

  // Destroyed without Commit() and without an exception: also rolled back.
  {
    Database::Transaction transaction(db);
    db.SetMeta("state", "uncommitted");
  }
  EXPECT_EQ(db.GetMeta("state"), "before");

  {
    Database::Transaction transaction(db);
    db.SetMeta("state", "committed");
    ExpectError([&] { Database::Transaction nested(db); }, {"do not nest"});
    transaction.Commit();
    ExpectError([&] { transaction.Commit(); }, {"committed twice"});
  }
  EXPECT_EQ(db.GetMeta("state"), "committed");
}

TEST_F(DatabaseFileTest, TransactionCommitsToTheFile) {
  const std::string path = PathOf("transaction.db");
  {
    Database db(path);
    Database::Transaction transaction(db);
    db.SetMeta("a", "1");
    db.SetMeta("b", "2");
    transaction.Commit();
  }
  Database db(path, Database::Mode::kReadOnly);
  EXPECT_EQ(db.GetMeta("a"), "1");
  EXPECT_EQ(db.GetMeta("b"), "2");
}

TEST_F(DatabaseFileTest, MigratesAnEmptyVersionZeroFile) {
  const std::string path = PathOf("empty.db");
  {
    RawConnection raw(path);
    raw.Exec("PRAGMA user_version = 0");
  }
  {
    Database db(path);
    EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
  }
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"),
            Database::LatestSchemaVersion());
  EXPECT_EQ(
      raw.QueryInt("SELECT count(*) FROM sqlite_schema WHERE name = 'frames'"),
      1);
  EXPECT_EQ(raw.QueryText("PRAGMA journal_mode"), "wal");
}

TEST_F(DatabaseFileTest, MigratesEveryOlderVersionAndKeepsItsData) {
  // A database made by hand with the first k migration files (as an older
  // epiloc left it), for every k below the latest; opening it applies the rest.
  // k = latest is a database that must open without migrating again (re-running
  // the migrations would fail).
  const auto files = MigrationFiles();
  for (size_t k = 1; k <= files.size(); ++k) {
    SCOPED_TRACE(fmt::format("database at version {}", k));
    const std::string path = PathOf(fmt::format("version_{}.db", k));
    {
      RawConnection raw(path);
      raw.Exec("BEGIN");
      for (size_t i = 0; i < k; ++i) raw.Exec(ReadText(files[i]));
      raw.Exec(fmt::format("PRAGMA user_version = {}", k));
      raw.Exec("INSERT INTO meta (key, value) VALUES ('made_at_version', '" +
               std::to_string(k) + "')");
      raw.Exec("COMMIT");
    }
    Database db(path);
    EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
    EXPECT_EQ(db.GetMeta("made_at_version"), std::to_string(k));
    const Sample sample = WriteSample(&db, 7);
    ExpectSample(sample, db);
  }
}

TEST_F(DatabaseFileTest, FailedMigrationLeavesTheFileUnchanged) {
  // A version-0 file holding a table of another program: never add epiloc's
  // tables to it.
  const std::string path = PathOf("other.db");
  {
    RawConnection raw(path);
    raw.Exec("CREATE TABLE photos (id INTEGER PRIMARY KEY)");
  }
  ExpectError([&] { Database db(path); }, {path, "not an epiloc one"});
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"), 0);
  EXPECT_EQ(raw.QueryInt("SELECT count(*) FROM sqlite_schema"), 1);
}

TEST_F(DatabaseFileTest, RefusesANewerSchemaVersion) {
  const std::string path = PathOf("newer.db");
  {
    Database db(path);
    db.SetMeta("k", "v");
  }
  {
    RawConnection raw(path);
    raw.Exec("PRAGMA user_version = 999");
  }
  const std::string message = fmt::format(
      "{}: database schema version 999 is newer than this epiloc ({}); "
      "upgrade epiloc",
      path, Database::LatestSchemaVersion());
  ExpectError([&] { Database db(path); }, {message});
  ExpectError([&] { Database db(path, Database::Mode::kReadOnly); }, {message});
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"), 999);
}

TEST_F(DatabaseFileTest, RefusesAFileThatIsNotSqlite) {
  const std::string path = PathOf("notes.db");
  {
    std::ofstream out(path);
    for (int i = 0; i < 100; ++i)
      out << "this is a text file, not a database\n";
  }
  ExpectError([&] { Database db(path); }, {path, "not an SQLite database"});
  ExpectError([&] { Database db(path, Database::Mode::kReadOnly); },
              {path, "not an SQLite database"});
  EXPECT_THAT(ReadText(path), HasSubstr("this is a text file"));
}

TEST_F(DatabaseFileTest, CannotCreateInAMissingDirectory) {
  const std::string path = PathOf("no/such/dir/route.db");
  ExpectError([&] { Database db(path); }, {path, "unable to open"});
}

TEST_F(DatabaseFileTest, LockedDatabaseFailsQuicklyWithAClearMessage) {
  const std::string path = PathOf("locked.db");
  Database db(path);
  db.SetMeta("k", "before");
  RawConnection other(path);
  other.Exec("BEGIN IMMEDIATE");
  other.Exec("INSERT INTO meta (key, value) VALUES ('other', 'writer')");

  const auto start = std::chrono::steady_clock::now();
  ExpectError([&] { db.SetMeta("k", "during"); },
              {path + ": database is locked by another process"});
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  EXPECT_GT(seconds, 1.0);  // waited for the busy timeout
  EXPECT_LT(seconds, 5.0);  // but did not hang
  ExpectError([&] { Database::Transaction transaction(db); },
              {"locked by another process"});
  std::mt19937 rng(8);
  DbFrame frame;
  frame.drive_id = 1;
  frame.frame = 0;
  ExpectError(
      [&] {
        db.WriteFrame(frame, RandomKeypoints(1, &rng),
                      RandomDescriptors(1, &rng));
      },
      {"locked by another process"});

  // Reading is not blocked by the other writer (write-ahead log), and nor is
  // opening.
  EXPECT_EQ(db.GetMeta("k"), "before");
  EXPECT_FALSE(db.GetMeta("other").has_value());
  {
    Database second(path);
    EXPECT_EQ(second.GetMeta("k"), "before");
  }
  other.Exec("COMMIT");
  db.SetMeta("k", "after");
  EXPECT_EQ(db.GetMeta("k"), "after");
  EXPECT_EQ(db.GetMeta("other"), "writer");
}

TEST_F(DatabaseFileTest, ReadOnlyModeReadsAndNeverWrites) {
  const std::string missing = PathOf("missing.db");
  ExpectError([&] { Database db(missing, Database::Mode::kReadOnly); },
              {missing});
  EXPECT_FALSE(fs::exists(missing));

  const std::string empty = PathOf("empty.db");
  { RawConnection raw(empty); }
  ExpectError([&] { Database db(empty, Database::Mode::kReadOnly); },
              {empty, "not an epiloc database"});

  const std::string path = PathOf("route.db");
  Sample sample;
  {
    Database db(path);
    sample = WriteSample(&db, 9);
  }
  Database db(path, Database::Mode::kReadOnly);
  ExpectSample(sample, db);
  ExpectError([&] { db.SetMeta("k", "v"); }, {path, "readonly"});
  ExpectError([&] { db.WriteRoute({}); }, {path, "readonly"});
  EXPECT_EQ(db.ReadRoute(), sample.route);
}

TEST_F(DatabaseFileTest, RetrievalModelAndGlobalDescriptorsRoundTrip) {
  const std::string path = PathOf("retrieval.db");
  Sample sample;
  const std::vector<uint8_t> model = {'E', 'G', 'D', 'M', 0, 255, 7};
  // Every float bit pattern that is finite survives, including -0 and denormals.
  const std::vector<float> first = {1.0f, -0.0f, 1e-40f, -3.25e38f};
  const std::vector<float> second = {0.5f, 0.25f, -0.125f, 2.0f};
  {
    Database db(path);
    sample = WriteSample(&db, 11);
    EXPECT_FALSE(db.ReadRetrievalModel().has_value());
    EXPECT_TRUE(db.ReadGlobalDescriptors().empty());
    db.WriteRetrievalModel({1, 2, 3}, 8, 4);
    db.WriteRetrievalModel(model, 64, 4);  // replaces
    db.WriteGlobalDescriptor(sample.frames[2].frame.image_id, second);
    db.WriteGlobalDescriptor(sample.frames[0].frame.image_id, second);
    db.WriteGlobalDescriptor(sample.frames[0].frame.image_id, first);  // replaces
    ExpectError([&] { db.WriteGlobalDescriptor(sample.frames[1].frame.image_id, {}); },
                {path, "empty global descriptor"});
    ExpectError(
        [&] {
          db.WriteGlobalDescriptor(sample.frames[1].frame.image_id,
                                   {std::numeric_limits<float>::quiet_NaN()});
        },
        {path, "non-finite"});
    ExpectError([&] { db.WriteGlobalDescriptor(999, first); }, {path, "FOREIGN KEY"});
  }
  {
    Database db(path, Database::Mode::kReadOnly);
    EXPECT_EQ(db.ReadRetrievalModel(), model);
    EXPECT_EQ(db.NumGlobalDescriptors(), 2);
    const auto descriptors = db.ReadGlobalDescriptors();
    ASSERT_EQ(descriptors.size(), 2u);
    EXPECT_EQ(descriptors[0].first, sample.frames[0].frame.image_id);
    EXPECT_EQ(descriptors[1].first, sample.frames[2].frame.image_id);
    ASSERT_EQ(descriptors[0].second.size(), first.size());
    for (size_t i = 0; i < first.size(); ++i) {
      EXPECT_EQ(std::memcmp(&descriptors[0].second[i], &first[i], 4), 0) << i;
    }
    EXPECT_EQ(descriptors[1].second, second);
  }
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryText("SELECT num_words || ' ' || dims FROM retrieval_model"), "64 4");
  // Little-endian float32: 1.0f is 00 00 80 3F.
  EXPECT_EQ(raw.QueryText("SELECT hex(substr(data, 1, 4)) FROM global_descriptors "
                          "ORDER BY image_id LIMIT 1"),
            "0000803F");
  raw.Exec("PRAGMA ignore_check_constraints = ON");
  raw.Exec("UPDATE global_descriptors SET dims = 5");
  {
    Database db(path);
    ExpectError([&] { db.ReadGlobalDescriptors(); },
                {path, "corrupt global descriptor blob for image"});
    // Deleting a frame deletes its descriptor; clearing deletes the rest.
    db.DeleteFrame(sample.frames[0].frame.image_id);
    EXPECT_EQ(db.NumGlobalDescriptors(), 1);
    db.ClearGlobalDescriptors();
    EXPECT_EQ(db.NumGlobalDescriptors(), 0);
    db.DeleteRetrievalModel();
    EXPECT_FALSE(db.ReadRetrievalModel().has_value());
  }
}

TEST_F(DatabaseFileTest, MigratingAVersionOneDatabaseKeepsItsFramesAndAddsRetrieval) {
  const auto files = MigrationFiles();
  ASSERT_GE(files.size(), 2u);
  const std::string path = PathOf("version_1.db");
  {
    // As epiloc 0.x left it: schema version 1 with a drive and a frame.
    RawConnection raw(path);
    raw.Exec("BEGIN");
    raw.Exec(ReadText(files[0]));
    raw.Exec("PRAGMA user_version = 1");
    raw.Exec("INSERT INTO drives (drive_id, name) VALUES (1, 'old')");
    raw.Exec(
        "INSERT INTO frames (image_id, drive_id, frame, timestamp_s, lat_deg, lon_deg, alt_m, "
        "e_m, n_m, u_m, heading_deg, s_m, num_features) "
        "VALUES (7, 1, 3, 12.5, 49.0, 8.4, 110.0, 1.0, 2.0, 3.0, 90.0, 4.5, 1)");
    raw.Exec("INSERT INTO keypoints VALUES (7, 1, 4, zeroblob(16))");
    raw.Exec("INSERT INTO descriptors VALUES (7, 1, 128, zeroblob(128))");
    raw.Exec("COMMIT");
  }
  {
    Database db(path);
    EXPECT_EQ(db.SchemaVersion(), Database::LatestSchemaVersion());
    const auto frames = db.ReadFrames();
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].image_id, 7);
    EXPECT_EQ(frames[0].frame, 3);
    EXPECT_EQ(frames[0].s_m, 4.5);
    EXPECT_EQ(db.ReadDescriptors(7).rows(), 1);
    EXPECT_FALSE(db.ReadRetrievalModel().has_value());
    EXPECT_EQ(db.NumGlobalDescriptors(), 0);
    db.WriteGlobalDescriptor(7, {1.0f, 0.0f});
    db.WriteRetrievalModel({1, 2}, 2, 2);
  }
  RawConnection raw(path);
  EXPECT_EQ(raw.QueryInt("PRAGMA user_version"), Database::LatestSchemaVersion());
  EXPECT_EQ(raw.QueryInt("SELECT count(*) FROM global_descriptors"), 1);
  EXPECT_EQ(raw.QueryInt("SELECT count(*) FROM frames"), 1);
}

}  // namespace
}  // namespace epiloc
