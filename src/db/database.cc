// Typed reads and writes of the route database tables.

#include "epiloc/db/database.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "database_internal.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using internal::Query;

constexpr int kKeypointCols = 4;
constexpr int kDescriptorCols = 128;
constexpr const char* kEnuLatKey = "enu_origin_lat_deg";
constexpr const char* kEnuLonKey = "enu_origin_lon_deg";
constexpr const char* kEnuAltKey = "enu_origin_alt_m";

// Keypoints as little-endian IEEE floats whatever the host byte order, so
// database files move between hosts.
std::vector<uint8_t> EncodeKeypoints(const FeatureKeypoints& keypoints) {
  std::vector<uint8_t> bytes(static_cast<size_t>(keypoints.size()) *
                             sizeof(float));
  const float* values = keypoints.data();
  for (Eigen::Index i = 0; i < keypoints.size(); ++i) {
    uint32_t bits;
    std::memcpy(&bits, &values[i], sizeof(bits));
    for (int b = 0; b < 4; ++b) {
      bytes[4 * i + b] = static_cast<uint8_t>(bits >> (8 * b));
    }
  }
  return bytes;
}

void DecodeKeypoints(const uint8_t* bytes, FeatureKeypoints* keypoints) {
  float* values = keypoints->data();
  for (Eigen::Index i = 0; i < keypoints->size(); ++i) {
    uint32_t bits = 0;
    for (int b = 0; b < 4; ++b) {
      bits |= static_cast<uint32_t>(bytes[4 * i + b]) << (8 * b);
    }
    std::memcpy(&values[i], &bits, sizeof(bits));
  }
}

// Any float array in the keypoint blobs' layout (little-endian IEEE floats).
std::vector<uint8_t> EncodeFloats(const float* values, size_t count) {
  std::vector<uint8_t> bytes(count * sizeof(float));
  for (size_t i = 0; i < count; ++i) {
    uint32_t bits;
    std::memcpy(&bits, &values[i], sizeof(bits));
    for (int b = 0; b < 4; ++b) bytes[4 * i + b] = static_cast<uint8_t>(bits >> (8 * b));
  }
  return bytes;
}

void DecodeFloats(const uint8_t* bytes, size_t count, float* values) {
  for (size_t i = 0; i < count; ++i) {
    uint32_t bits = 0;
    for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(bytes[4 * i + b]) << (8 * b);
    std::memcpy(&values[i], &bits, sizeof(bits));
  }
}

// "?, ?, ..., ?" with n parameters.
std::string Placeholders(int n) {
  std::string text;
  for (int i = 0; i < n; ++i) text += i == 0 ? "?" : ", ?";
  return text;
}

const std::string kCameraColumns =
    "width, height, fx, fy, cx, cy, k1, k2, p1, p2, k3, "
    "orig_width, orig_height, orig_fx, orig_fy, orig_cx, orig_cy, "
    "orig_k1, orig_k2, orig_p1, orig_p2, orig_k3";
const std::string kDriveColumns =
    "drive_id, name, source_dir, camera_id, positions, num_frames_planned, "
    "complete";
const std::string kFrameColumns =
    "image_id, drive_id, frame, timestamp_s, image_path, image_hash, "
    "lat_deg, lon_deg, alt_m, e_m, n_m, u_m, heading_deg, s_m, "
    "qw, qx, qy, qz, num_features";

void BindCamera(const Camera& camera, Query* query) {
  query->Bind(camera.width).Bind(camera.height).Bind(camera.fx).Bind(camera.fy);
  query->Bind(camera.cx).Bind(camera.cy);
  for (const double d : camera.distortion) query->Bind(d);
}

Camera ReadCameraColumns(Query* query) {
  Camera camera;
  camera.width = static_cast<int>(query->Int());
  camera.height = static_cast<int>(query->Int());
  camera.fx = query->Double();
  camera.fy = query->Double();
  camera.cx = query->Double();
  camera.cy = query->Double();
  for (double& d : camera.distortion) d = query->Double();
  return camera;
}

DbDrive ReadDriveRow(Query* query) {
  DbDrive drive;
  drive.drive_id = query->Int();
  drive.name = query->Text();
  drive.source_dir = query->Text();
  if (query->IsNull()) {
    query->Skip();
  } else {
    drive.camera_id = query->Int();
  }
  drive.positions = query->Text();
  drive.num_frames_planned = query->Int();
  drive.complete = query->Int() != 0;
  return drive;
}

DbFrame ReadFrameRow(Query* query) {
  DbFrame frame;
  frame.image_id = query->Int();
  frame.drive_id = query->Int();
  frame.frame = query->Int();
  frame.timestamp_s = query->Double();
  frame.image_path = query->Text();
  frame.image_hash = query->Text();
  frame.position.lat_deg = query->Double();
  frame.position.lon_deg = query->Double();
  frame.position.alt_m = query->Double();
  for (int i = 0; i < 3; ++i) frame.center_in_enu[i] = query->Double();
  frame.heading_deg = query->Double();
  frame.s_m = query->Double();
  if (query->IsNull()) {
    for (int i = 0; i < 4; ++i) query->Skip();
  } else {
    const double w = query->Double();
    const double x = query->Double();
    const double y = query->Double();
    const double z = query->Double();
    frame.enu_from_cam = Eigen::Quaterniond(w, x, y, z);
  }
  frame.num_features = static_cast<int>(query->Int());
  return frame;
}

// Makes one multi-statement write atomic, inside or outside a
// Database::Transaction: released on success, rolled back to its start when
// destroyed without Release().
class Savepoint {
 public:
  Savepoint(sqlite3_stmt* savepoint,
            sqlite3_stmt* release,
            sqlite3_stmt* rollback_to,
            const std::string& path)
      : release_(release), rollback_to_(rollback_to), path_(path) {
    Query(savepoint, path_, "starting a write").Run();
  }
  ~Savepoint() {
    if (released_) return;
    // Undo the partial write and drop the savepoint; errors here would hide
    // the first one.
    try {
      Query(rollback_to_, path_, "undoing a failed write").Run();
      Query(release_, path_, "undoing a failed write").Run();
    } catch (const Error&) {
    }
  }
  Savepoint(const Savepoint&) = delete;
  Savepoint& operator=(const Savepoint&) = delete;

  void Release() {
    Query(release_, path_, "finishing a write").Run();
    released_ = true;
  }

 private:
  sqlite3_stmt* release_;
  sqlite3_stmt* rollback_to_;
  const std::string& path_;
  bool released_ = false;
};

}  // namespace

void Database::Impl::PrepareStatements() {
  schema_version = Prepare("PRAGMA user_version");
  begin = Prepare("BEGIN IMMEDIATE");
  commit = Prepare("COMMIT");
  rollback = Prepare("ROLLBACK");
  savepoint = Prepare("SAVEPOINT epiloc_write");
  release = Prepare("RELEASE epiloc_write");
  rollback_to = Prepare("ROLLBACK TO epiloc_write");
  set_meta = Prepare(
      "INSERT INTO meta (key, value) VALUES (?, ?) "
      "ON CONFLICT (key) DO UPDATE SET value = excluded.value");
  get_meta = Prepare("SELECT value FROM meta WHERE key = ?");
  write_camera = Prepare("INSERT INTO cameras (" + kCameraColumns +
                         ") VALUES (" + Placeholders(22) + ")");
  read_camera =
      Prepare("SELECT " + kCameraColumns + " FROM cameras WHERE camera_id = ?");
  write_drive = Prepare(
      "INSERT INTO drives (name, source_dir, camera_id, positions, "
      "num_frames_planned, complete) VALUES (" +
      Placeholders(6) + ")");
  update_drive = Prepare(
      "UPDATE drives SET name = ?, source_dir = ?, camera_id = ?, "
      "positions = ?, num_frames_planned = ?, complete = ? "
      "WHERE drive_id = ?");
  find_drive =
      Prepare("SELECT " + kDriveColumns + " FROM drives WHERE name = ?");
  read_drives =
      Prepare("SELECT " + kDriveColumns + " FROM drives ORDER BY drive_id");
  // image_id NULL: SQLite assigns the next row id.
  write_frame = Prepare("INSERT INTO frames (" + kFrameColumns +
                        ") VALUES (NULL, " + Placeholders(18) + ")");
  has_frame = Prepare("SELECT 1 FROM frames WHERE drive_id = ? AND frame = ?");
  delete_frame = Prepare("DELETE FROM frames WHERE image_id = ?");
  delete_drive = Prepare("DELETE FROM drives WHERE drive_id = ?");
  delete_unused_camera = Prepare(
      "DELETE FROM cameras WHERE camera_id = ? AND NOT EXISTS "
      "(SELECT 1 FROM drives WHERE drives.camera_id = cameras.camera_id)");
  delete_meta = Prepare("DELETE FROM meta WHERE key = ?");
  read_frame =
      Prepare("SELECT " + kFrameColumns + " FROM frames WHERE image_id = ?");
  read_drive_frames =
      Prepare("SELECT " + kFrameColumns +
              " FROM frames WHERE drive_id = ? ORDER BY timestamp_s, frame");
  read_all_frames =
      Prepare("SELECT " + kFrameColumns +
              " FROM frames ORDER BY drive_id, timestamp_s, frame");
  count_drive_frames =
      Prepare("SELECT count(*) FROM frames WHERE drive_id = ?");
  count_frames = Prepare("SELECT count(*) FROM frames");
  count_features = Prepare("SELECT COALESCE(SUM(num_features), 0) FROM frames");
  write_keypoints = Prepare(
      "INSERT INTO keypoints (image_id, rows, cols, data) VALUES (?, ?, ?, ?)");
  read_keypoints =
      Prepare("SELECT rows, cols, data FROM keypoints WHERE image_id = ?");
  write_descriptors = Prepare(
      "INSERT INTO descriptors (image_id, rows, cols, data) "
      "VALUES (?, ?, ?, ?)");
  read_descriptors =
      Prepare("SELECT rows, cols, data FROM descriptors WHERE image_id = ?");
  clear_route = Prepare("DELETE FROM route_points");
  write_route_point = Prepare(
      "INSERT INTO route_points (idx, e_m, n_m, u_m) VALUES (?, ?, ?, ?)");
  read_route = Prepare("SELECT e_m, n_m, u_m FROM route_points ORDER BY idx");
  write_retrieval_model = Prepare(
      "INSERT OR REPLACE INTO retrieval_model (id, num_words, dims, data) "
      "VALUES (1, ?, ?, ?)");
  read_retrieval_model = Prepare("SELECT data FROM retrieval_model WHERE id = 1");
  delete_retrieval_model = Prepare("DELETE FROM retrieval_model");
  write_global_descriptor = Prepare(
      "INSERT OR REPLACE INTO global_descriptors (image_id, dims, data) "
      "VALUES (?, ?, ?)");
  read_global_descriptors =
      Prepare("SELECT image_id, dims, data FROM global_descriptors ORDER BY image_id");
  count_global_descriptors = Prepare("SELECT count(*) FROM global_descriptors");
  clear_global_descriptors = Prepare("DELETE FROM global_descriptors");
  write_point = Prepare(
      "INSERT INTO points3d (e_m, n_m, u_m, error_px, num_observations) VALUES (?, ?, ?, ?, ?)");
  write_observation =
      Prepare("INSERT INTO observations (image_id, feature_index, point_id) VALUES (?, ?, ?)");
  read_frame_points = Prepare(
      "SELECT o.feature_index, p.point_id, p.e_m, p.n_m, p.u_m FROM observations o "
      "JOIN points3d p ON p.point_id = o.point_id WHERE o.image_id = ? "
      "ORDER BY o.feature_index");
  count_points = Prepare("SELECT count(*) FROM points3d");
  count_observations = Prepare("SELECT count(*) FROM observations");
  clear_points = Prepare("DELETE FROM points3d");  // observations go with them (ON DELETE CASCADE)
}

void Database::SetMeta(const std::string& key, const std::string& value) {
  Query(impl_->set_meta, path_, "writing metadata").Bind(key).Bind(value).Run();
}

std::optional<std::string> Database::GetMeta(const std::string& key) const {
  Query query(impl_->get_meta, path_, "reading metadata");
  query.Bind(key);
  if (!query.Step()) return std::nullopt;
  return query.Text();
}

std::optional<Geodetic> Database::EnuOrigin() const {
  const auto lat = GetMeta(kEnuLatKey);
  const auto lon = GetMeta(kEnuLonKey);
  const auto alt = GetMeta(kEnuAltKey);
  if (!lat && !lon && !alt) return std::nullopt;
  if (!lat || !lon || !alt) {
    Throw("{}: incomplete ENU origin in table meta", path_);
  }
  Geodetic origin;
  origin.lat_deg =
      ParseDouble(*lat, fmt::format("{}: meta {}", path_, kEnuLatKey));
  origin.lon_deg =
      ParseDouble(*lon, fmt::format("{}: meta {}", path_, kEnuLonKey));
  origin.alt_m =
      ParseDouble(*alt, fmt::format("{}: meta {}", path_, kEnuAltKey));
  CheckGeodetic(origin, fmt::format("{}: ENU origin", path_));
  return origin;
}

void Database::SetEnuOrigin(const Geodetic& origin) {
  CheckGeodetic(origin, fmt::format("{}: ENU origin", path_));
  if (const auto existing = EnuOrigin()) {
    if (existing->lat_deg == origin.lat_deg &&
        existing->lon_deg == origin.lon_deg &&
        existing->alt_m == origin.alt_m) {
      return;
    }
    Throw(
        "{}: the ENU origin is already ({}, {}, {}); every position in the "
        "database is relative to it, so it cannot change",
        path_, existing->lat_deg, existing->lon_deg, existing->alt_m);
  }
  Savepoint savepoint(impl_->savepoint, impl_->release, impl_->rollback_to,
                      path_);
  SetMeta(kEnuLatKey, FormatDouble(origin.lat_deg));
  SetMeta(kEnuLonKey, FormatDouble(origin.lon_deg));
  SetMeta(kEnuAltKey, FormatDouble(origin.alt_m));
  savepoint.Release();
}

camera_t Database::WriteCamera(const DbCamera& camera) {
  camera.camera.Check(fmt::format("{}: feature camera", path_));
  camera.original.Check(fmt::format("{}: original camera", path_));
  Query query(impl_->write_camera, path_, "writing a camera");
  BindCamera(camera.camera, &query);
  BindCamera(camera.original, &query);
  query.Run();
  return sqlite3_last_insert_rowid(impl_->db());
}

DbCamera Database::ReadCamera(camera_t camera_id) const {
  Query query(impl_->read_camera, path_, "reading a camera");
  query.Bind(camera_id);
  if (!query.Step()) Throw("{}: no camera {}", path_, camera_id);
  DbCamera camera;
  camera.camera_id = camera_id;
  camera.camera = ReadCameraColumns(&query);
  camera.original = ReadCameraColumns(&query);
  return camera;
}

namespace {

void BindDrive(const DbDrive& drive, Query* query) {
  query->Bind(drive.name).Bind(drive.source_dir);
  if (drive.camera_id == kInvalidCamera) {
    query->BindNull();
  } else {
    query->Bind(drive.camera_id);
  }
  query->Bind(drive.positions)
      .Bind(drive.num_frames_planned)
      .Bind(drive.complete ? 1 : 0);
}

}  // namespace

drive_t Database::WriteDrive(const DbDrive& drive) {
  const std::string what = fmt::format("writing drive '{}'", drive.name);
  Query query(impl_->write_drive, path_, what);
  BindDrive(drive, &query);
  query.Run();
  return sqlite3_last_insert_rowid(impl_->db());
}

void Database::UpdateDrive(const DbDrive& drive) {
  const std::string what =
      fmt::format("updating drive {} '{}'", drive.drive_id, drive.name);
  Query query(impl_->update_drive, path_, what);
  BindDrive(drive, &query);
  query.Bind(drive.drive_id).Run();
  if (sqlite3_changes(impl_->db()) == 0) {
    Throw("{}: no drive {} to update", path_, drive.drive_id);
  }
}

std::optional<DbDrive> Database::FindDrive(const std::string& name) const {
  Query query(impl_->find_drive, path_, "reading a drive");
  query.Bind(name);
  if (!query.Step()) return std::nullopt;
  return ReadDriveRow(&query);
}

std::vector<DbDrive> Database::ReadDrives() const {
  Query query(impl_->read_drives, path_, "reading drives");
  std::vector<DbDrive> drives;
  while (query.Step()) drives.push_back(ReadDriveRow(&query));
  return drives;
}

image_t Database::WriteFrame(const DbFrame& frame,
                             const FeatureKeypoints& keypoints,
                             const FeatureDescriptors& descriptors) {
  const std::string where = fmt::format("{}: frame {} of drive {}", path_,
                                        frame.frame, frame.drive_id);
  EPILOC_CHECK(frame.frame >= 0, "{}: frame number must not be negative",
               where);
  CheckGeodetic(frame.position, where);
  EPILOC_CHECK(
      std::isfinite(frame.timestamp_s) && frame.center_in_enu.allFinite() &&
          std::isfinite(frame.s_m),
      "{}: timestamp, ENU position and along-route distance must be finite",
      where);
  EPILOC_CHECK(frame.heading_deg >= 0.0 && frame.heading_deg < 360.0,
               "{}: heading {} deg out of range [0, 360)", where,
               frame.heading_deg);
  EPILOC_CHECK(keypoints.rows() == descriptors.rows(),
               "{}: {} keypoints but {} descriptors", where, keypoints.rows(),
               descriptors.rows());
  Eigen::Quaterniond enu_from_cam = Eigen::Quaterniond::Identity();
  if (frame.enu_from_cam) {
    EPILOC_CHECK(frame.enu_from_cam->coeffs().allFinite() &&
                     frame.enu_from_cam->norm() > 0.5,
                 "{}: orientation is not a unit quaternion", where);
    enu_from_cam = frame.enu_from_cam->normalized();
  }
  if (HasFrame(frame.drive_id, frame.frame)) {
    Throw("{}: already in the database", where);
  }

  Savepoint savepoint(impl_->savepoint, impl_->release, impl_->rollback_to,
                      path_);
  {
    Query query(impl_->write_frame, path_, "writing a frame");
    query.Bind(frame.drive_id).Bind(frame.frame).Bind(frame.timestamp_s);
    query.Bind(frame.image_path).Bind(frame.image_hash);
    query.Bind(frame.position.lat_deg)
        .Bind(frame.position.lon_deg)
        .Bind(frame.position.alt_m);
    for (int i = 0; i < 3; ++i) query.Bind(frame.center_in_enu[i]);
    query.Bind(frame.heading_deg).Bind(frame.s_m);
    if (frame.enu_from_cam) {
      query.Bind(enu_from_cam.w()).Bind(enu_from_cam.x());
      query.Bind(enu_from_cam.y()).Bind(enu_from_cam.z());
    } else {
      query.BindNull().BindNull().BindNull().BindNull();
    }
    // The feature count is that of the stored keypoints, whatever
    // frame.num_features says.
    query.Bind(static_cast<int64_t>(keypoints.rows()));
    query.Run();
  }
  const image_t image_id = sqlite3_last_insert_rowid(impl_->db());
  Query(impl_->write_keypoints, path_, "writing keypoints")
      .Bind(image_id)
      .Bind(static_cast<int64_t>(keypoints.rows()))
      .Bind(kKeypointCols)
      .BindBlob(EncodeKeypoints(keypoints))
      .Run();
  const std::vector<uint8_t> descriptor_bytes(
      descriptors.data(), descriptors.data() + descriptors.size());
  Query(impl_->write_descriptors, path_, "writing descriptors")
      .Bind(image_id)
      .Bind(static_cast<int64_t>(descriptors.rows()))
      .Bind(kDescriptorCols)
      .BindBlob(descriptor_bytes)
      .Run();
  savepoint.Release();
  return image_id;
}

bool Database::HasFrame(drive_t drive_id, frame_t frame) const {
  Query query(impl_->has_frame, path_, "looking up a frame");
  query.Bind(drive_id).Bind(frame);
  return query.Step();
}

DbFrame Database::ReadFrame(image_t image_id) const {
  Query query(impl_->read_frame, path_, "reading a frame");
  query.Bind(image_id);
  if (!query.Step()) Throw("{}: no image {}", path_, image_id);
  return ReadFrameRow(&query);
}

std::vector<DbFrame> Database::ReadFrames(drive_t drive_id) const {
  const bool all = drive_id == kInvalidDrive;
  Query query(all ? impl_->read_all_frames : impl_->read_drive_frames, path_,
              "reading frames");
  if (!all) query.Bind(drive_id);
  std::vector<DbFrame> frames;
  while (query.Step()) frames.push_back(ReadFrameRow(&query));
  return frames;
}

namespace {

// Reads (rows, cols, data) and checks the shape; returns the blob bytes
// (nullptr if empty).
const uint8_t* ReadBlobShape(Query* query,
                             const std::string& path,
                             const char* kind,
                             image_t image_id,
                             int expected_cols,
                             size_t element_size,
                             int64_t* rows) {
  if (!query->Step()) Throw("{}: no {} for image {}", path, kind, image_id);
  *rows = query->Int();
  const int64_t cols = query->Int();
  const auto [data, bytes] = query->Blob();
  // Divide rather than multiply, so a corrupt huge row count cannot overflow.
  const bool ok = *rows >= 0 && cols == expected_cols &&
                  bytes % (cols * static_cast<int64_t>(element_size)) == 0 &&
                  bytes / (cols * static_cast<int64_t>(element_size)) == *rows;
  if (!ok) {
    Throw("{}: corrupt {} blob for image {} ({} x {} values in {} bytes)", path,
          kind, image_id, *rows, cols, bytes);
  }
  return data;
}

}  // namespace

FeatureKeypoints Database::ReadKeypoints(image_t image_id) const {
  Query query(impl_->read_keypoints, path_, "reading keypoints");
  query.Bind(image_id);
  int64_t rows = 0;
  const uint8_t* data = ReadBlobShape(&query, path_, "keypoints", image_id,
                                      kKeypointCols, sizeof(float), &rows);
  FeatureKeypoints keypoints(rows, kKeypointCols);
  if (rows > 0) DecodeKeypoints(data, &keypoints);
  return keypoints;
}

FeatureDescriptors Database::ReadDescriptors(image_t image_id) const {
  Query query(impl_->read_descriptors, path_, "reading descriptors");
  query.Bind(image_id);
  int64_t rows = 0;
  const uint8_t* data = ReadBlobShape(&query, path_, "descriptors", image_id,
                                      kDescriptorCols, 1, &rows);
  FeatureDescriptors descriptors(rows, kDescriptorCols);
  if (rows > 0) {
    std::memcpy(descriptors.data(), data,
                static_cast<size_t>(descriptors.size()));
  }
  return descriptors;
}

int64_t Database::NumFrames(drive_t drive_id) const {
  const bool all = drive_id == kInvalidDrive;
  Query query(all ? impl_->count_frames : impl_->count_drive_frames, path_,
              "counting frames");
  if (!all) query.Bind(drive_id);
  return query.Step() ? query.Int() : 0;
}

int64_t Database::NumFeatures() const {
  Query query(impl_->count_features, path_, "counting features");
  return query.Step() ? query.Int() : 0;
}

void Database::WriteRoute(const std::vector<Eigen::Vector3d>& points_in_enu) {
  for (const auto& point : points_in_enu) {
    EPILOC_CHECK(point.allFinite(), "{}: route point is not finite", path_);
  }
  Savepoint savepoint(impl_->savepoint, impl_->release, impl_->rollback_to,
                      path_);
  Query(impl_->clear_route, path_, "clearing the route").Run();
  for (size_t i = 0; i < points_in_enu.size(); ++i) {
    const Eigen::Vector3d& p = points_in_enu[i];
    Query(impl_->write_route_point, path_, "writing the route")
        .Bind(static_cast<int64_t>(i))
        .Bind(p.x())
        .Bind(p.y())
        .Bind(p.z())
        .Run();
  }
  savepoint.Release();
}

std::vector<Eigen::Vector3d> Database::ReadRoute() const {
  Query query(impl_->read_route, path_, "reading the route");
  std::vector<Eigen::Vector3d> points;
  while (query.Step()) {
    Eigen::Vector3d p;
    for (int i = 0; i < 3; ++i) p[i] = query.Double();
    points.push_back(p);
  }
  return points;
}

void Database::WriteRetrievalModel(const std::vector<uint8_t>& data, int num_words, int dims) {
  EPILOC_CHECK(!data.empty() && num_words > 0 && dims > 0,
               "{}: invalid retrieval model ({} bytes, {} words, {} dimensions)", path_,
               data.size(), num_words, dims);
  Query(impl_->write_retrieval_model, path_, "writing the retrieval model")
      .Bind(num_words)
      .Bind(dims)
      .BindBlob(data)
      .Run();
}

std::optional<std::vector<uint8_t>> Database::ReadRetrievalModel() const {
  Query query(impl_->read_retrieval_model, path_, "reading the retrieval model");
  if (!query.Step()) return std::nullopt;
  const auto [data, bytes] = query.Blob();
  if (bytes == 0) return std::vector<uint8_t>();
  return std::vector<uint8_t>(data, data + bytes);
}

void Database::DeleteRetrievalModel() {
  Query(impl_->delete_retrieval_model, path_, "deleting the retrieval model").Run();
}

void Database::WriteGlobalDescriptor(image_t image_id, const std::vector<float>& descriptor) {
  EPILOC_CHECK(!descriptor.empty(), "{}: empty global descriptor for image {}", path_, image_id);
  for (const float value : descriptor) {
    EPILOC_CHECK(std::isfinite(value), "{}: non-finite global descriptor for image {}", path_,
                 image_id);
  }
  Query(impl_->write_global_descriptor, path_,
        fmt::format("writing the global descriptor of image {}", image_id))
      .Bind(image_id)
      .Bind(static_cast<int64_t>(descriptor.size()))
      .BindBlob(EncodeFloats(descriptor.data(), descriptor.size()))
      .Run();
}

std::vector<std::pair<image_t, std::vector<float>>> Database::ReadGlobalDescriptors() const {
  Query query(impl_->read_global_descriptors, path_, "reading global descriptors");
  std::vector<std::pair<image_t, std::vector<float>>> descriptors;
  while (query.Step()) {
    const image_t image_id = query.Int();
    const int64_t dims = query.Int();
    const auto [data, bytes] = query.Blob();
    if (dims <= 0 || bytes % 4 != 0 || bytes / 4 != dims) {
      Throw("{}: corrupt global descriptor blob for image {} ({} values in {} bytes)", path_,
            image_id, dims, bytes);
    }
    std::vector<float> values(static_cast<size_t>(dims));
    DecodeFloats(data, values.size(), values.data());
    descriptors.emplace_back(image_id, std::move(values));
  }
  return descriptors;
}

int64_t Database::NumGlobalDescriptors() const {
  Query query(impl_->count_global_descriptors, path_, "counting global descriptors");
  return query.Step() ? query.Int() : 0;
}

void Database::ClearGlobalDescriptors() {
  Query(impl_->clear_global_descriptors, path_, "clearing global descriptors").Run();
}

int64_t Database::WritePoint(const DbPoint3d& point,
                             const std::vector<DbObservation>& observations) {
  EPILOC_CHECK(point.position_in_enu.allFinite() && std::isfinite(point.error_px) &&
                   point.error_px >= 0,
               "{}: invalid 3-D point (position or error not finite)", path_);
  EPILOC_CHECK(observations.size() >= 2, "{}: a 3-D point needs at least 2 observations, got {}",
               path_, observations.size());
  Savepoint savepoint(impl_->savepoint, impl_->release, impl_->rollback_to, path_);
  Query(impl_->write_point, path_, "writing a 3-D point")
      .Bind(point.position_in_enu.x())
      .Bind(point.position_in_enu.y())
      .Bind(point.position_in_enu.z())
      .Bind(point.error_px)
      .Bind(static_cast<int64_t>(observations.size()))
      .Run();
  const int64_t point_id = sqlite3_last_insert_rowid(sqlite3_db_handle(impl_->write_point));
  for (const DbObservation& o : observations) {
    Query(impl_->write_observation, path_,
          fmt::format("writing an observation of image {} feature {}", o.image_id,
                      o.feature_index))
        .Bind(o.image_id)
        .Bind(o.feature_index)
        .Bind(point_id)
        .Run();
  }
  savepoint.Release();
  return point_id;
}

std::vector<DbFramePoint> Database::ReadFramePoints(image_t image_id) const {
  Query query(impl_->read_frame_points, path_,
              fmt::format("reading the 3-D points of image {}", image_id));
  query.Bind(image_id);
  std::vector<DbFramePoint> points;
  while (query.Step()) {
    DbFramePoint p;
    // Checked before narrowing: a damaged file's index may be negative or past int (the schema's
    // CHECK is not enforced on files other tools wrote), and callers index feature rows with it.
    const int64_t feature_index = query.Int();
    p.point_id = query.Int();
    const double e = query.Double(), n = query.Double(), u = query.Double();
    p.position_in_enu = Eigen::Vector3d(e, n, u);
    if (feature_index < 0 || feature_index > std::numeric_limits<int>::max() ||
        !p.position_in_enu.allFinite()) {
      Throw("{}: corrupt observation of 3-D point {} by image {} (feature {}, position {} {} {})",
            path_, p.point_id, image_id, feature_index, e, n, u);
    }
    p.feature_index = static_cast<int>(feature_index);
    points.push_back(p);
  }
  return points;
}

int64_t Database::NumPoints() const {
  Query query(impl_->count_points, path_, "counting 3-D points");
  return query.Step() ? query.Int() : 0;
}

int64_t Database::NumObservations() const {
  Query query(impl_->count_observations, path_, "counting observations");
  return query.Step() ? query.Int() : 0;
}

void Database::ClearPoints() {
  Query(impl_->clear_points, path_, "clearing 3-D points").Run();
}

void Database::DeleteFrame(image_t image_id) {
  // Keypoints and descriptors go with the frame (ON DELETE CASCADE).
  Query(impl_->delete_frame, path_, "deleting a frame").Bind(image_id).Run();
}

void Database::DeleteDrive(drive_t drive_id) {
  Savepoint savepoint(impl_->savepoint, impl_->release, impl_->rollback_to, path_);
  camera_t camera_id = kInvalidCamera;
  for (const DbDrive& drive : ReadDrives()) {
    if (drive.drive_id == drive_id) camera_id = drive.camera_id;
  }
  Query(impl_->delete_drive, path_, "deleting a drive").Bind(drive_id).Run();
  if (camera_id != kInvalidCamera) {
    Query(impl_->delete_unused_camera, path_, "deleting a camera").Bind(camera_id).Run();
  }
  savepoint.Release();
}

void Database::ClearRouteAndOrigin() {
  Savepoint savepoint(impl_->savepoint, impl_->release, impl_->rollback_to, path_);
  Query(impl_->clear_route, path_, "clearing the route").Run();
  for (const char* key : {kEnuLatKey, kEnuLonKey, kEnuAltKey}) {
    Query(impl_->delete_meta, path_, "clearing the ENU origin").Bind(std::string(key)).Run();
  }
  savepoint.Release();
}

}  // namespace epiloc
