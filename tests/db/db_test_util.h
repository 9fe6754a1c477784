// Fixtures and helpers shared by the database tests (each test file gets its own copy: the
// helpers live in an anonymous namespace).
#pragma once

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

[[maybe_unused]] std::string ReadText(const fs::path& path) {
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

}  // namespace
}  // namespace epiloc
