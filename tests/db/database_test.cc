// The database on :memory: and on files: every table round trip, blobs, constraints, ordering,
// transactions.
#include "db_test_util.h"

namespace epiloc {
namespace {

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

}  // namespace
}  // namespace epiloc

namespace epiloc {
namespace {

TEST(Database, PointsRoundTripByFrameAndFeature) {
  Database db(":memory:");
  const Sample sample = WriteSample(&db, 3);
  const image_t a = sample.frames[0].frame.image_id;  // 7 features
  const image_t c = sample.frames[2].frame.image_id;  // 300 features
  EXPECT_EQ(db.NumPoints(), 0);
  EXPECT_TRUE(db.ReadFramePoints(a).empty());
  DbPoint3d p1;
  p1.position_in_enu = {1.25, -2.5, 0.125};
  p1.error_px = 0.3;
  DbPoint3d p2;
  p2.position_in_enu = {10.0, 20.0, -1.0};
  p2.error_px = 0.0;
  int64_t id1, id2;
  {
    Database::Transaction transaction(db);
    id1 = db.WritePoint(p1, {{a, 5}, {c, 17}});
    id2 = db.WritePoint(p2, {{a, 2}, {c, 299}});
    transaction.Commit();
  }
  EXPECT_NE(id1, id2);
  EXPECT_EQ(db.NumPoints(), 2);
  EXPECT_EQ(db.NumObservations(), 4);
  const std::vector<DbFramePoint> seen = db.ReadFramePoints(a);
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].feature_index, 2);  // by ascending feature index
  EXPECT_EQ(seen[0].point_id, id2);
  EXPECT_EQ(seen[0].position_in_enu, p2.position_in_enu);
  EXPECT_EQ(seen[1].feature_index, 5);
  EXPECT_EQ(seen[1].point_id, id1);
  EXPECT_EQ(seen[1].position_in_enu, p1.position_in_enu);
  EXPECT_EQ(db.ReadFramePoints(c).size(), 2u);

  // Deleting a frame takes its observations; clearing takes everything.
  db.DeleteFrame(a);
  EXPECT_EQ(db.NumObservations(), 2);
  db.ClearPoints();
  EXPECT_EQ(db.NumPoints(), 0);
  EXPECT_EQ(db.NumObservations(), 0);
  EXPECT_TRUE(db.ReadFramePoints(c).empty());
}

TEST(Database, InvalidPointsAreRejectedWithoutTrace) {
  Database db(":memory:");
  const Sample sample = WriteSample(&db, 4);
  const image_t a = sample.frames[0].frame.image_id;
  const image_t c = sample.frames[2].frame.image_id;
  DbPoint3d p;
  p.position_in_enu = {1, 2, 3};
  db.WritePoint(p, {{a, 0}, {c, 0}});
  // A feature that already sees a point, one observation only, an unknown frame, a NaN.
  ExpectError([&] { db.WritePoint(p, {{a, 1}, {c, 0}}); }, {"observation of image"});
  ExpectError([&] { db.WritePoint(p, {{a, 1}}); }, {"at least 2 observations"});
  ExpectError([&] { db.WritePoint(p, {{a, 1}, {999, 0}}); }, {"observation of image 999"});
  DbPoint3d bad = p;
  bad.position_in_enu.x() = NAN;
  ExpectError([&] { db.WritePoint(bad, {{a, 1}, {c, 1}}); }, {"invalid 3-D point"});
  EXPECT_EQ(db.NumPoints(), 1);
  EXPECT_EQ(db.NumObservations(), 2);
}

// Found by the db_blob fuzz harness: an observation's feature index from a damaged file (past the
// schema's CHECK) came back negative, or wrapped to negative from past int, and the localizer
// indexes the frame's descriptor rows with it.
TEST_F(DatabaseFileTest, CorruptPointObservationsAreDetected) {
  const std::string path = PathOf("corrupt_points.db");
  image_t a = kInvalidImage;
  {
    Database db(path);
    const Sample sample = WriteSample(&db, 5);
    a = sample.frames[0].frame.image_id;
    DbPoint3d p;
    p.position_in_enu = {1, 2, 3};
    db.WritePoint(p, {{a, 3}, {sample.frames[2].frame.image_id, 4}});
  }
  const std::string where = fmt::format("corrupt observation of 3-D point 1 by image {}", a);
  for (const char* sql : {"UPDATE observations SET feature_index = -1",
                          "UPDATE observations SET feature_index = 4294967295",
                          "UPDATE observations SET feature_index = 3; "
                          "UPDATE points3d SET n_m = 9e999"}) {
    SCOPED_TRACE(sql);
    {
      RawConnection raw(path);
      raw.Exec("PRAGMA ignore_check_constraints = ON");
      raw.Exec(sql);
    }
    Database db(path, Database::Mode::kReadOnly);
    ExpectError([&] { db.ReadFramePoints(a); }, {path, where});
  }
  RawConnection(path).Exec("UPDATE points3d SET n_m = 2");
  Database db(path, Database::Mode::kReadOnly);
  ASSERT_EQ(db.ReadFramePoints(a).size(), 1u);
  EXPECT_EQ(db.ReadFramePoints(a)[0].feature_index, 3);
}

}  // namespace
}  // namespace epiloc
