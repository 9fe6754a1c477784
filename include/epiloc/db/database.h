// The route database: an SQLite file of cameras, drives, frames with positions, the route
// polyline and per-frame SIFT features. Schema: db_schema/*.sql (numbered migrations, applied in
// one transaction, PRAGMA user_version = last applied); blob layout: db_schema/README.md.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "epiloc/camera/camera.h"
#include "epiloc/core/types.h"
#include "epiloc/feature/types.h"
#include "epiloc/geo/geodetic.h"

struct sqlite3;
struct sqlite3_stmt;

namespace epiloc {

struct DbCamera {
  camera_t camera_id = kInvalidCamera;
  Camera camera;    // the distortion-free pinhole camera the features were extracted in
  Camera original;  // the calibration of the drive's images as stored
};

struct DbDrive {
  drive_t drive_id = kInvalidDrive;
  std::string name;        // unique
  std::string source_dir;  // the drive directory it was built from
  camera_t camera_id = kInvalidCamera;
  std::string positions;   // where frame positions came from: "ground_truth", "gnss", a file
  int64_t num_frames_planned = 0;  // frames with a position when the build started
  bool complete = false;   // all planned frames are in the database
};

struct DbFrame {
  image_t image_id = kInvalidImage;
  drive_t drive_id = kInvalidDrive;
  frame_t frame = kInvalidFrame;  // the drive's own frame number
  double timestamp_s = 0.0;
  std::string image_path;  // absolute path of the image file (empty for a video frame)
  std::string image_hash;  // XXH3-128 of the image file (or of the decoded frame for video)
  Geodetic position;       // camera optical centre
  Eigen::Vector3d center_in_enu = Eigen::Vector3d::Zero();  // in the database's ENU frame
  double heading_deg = 0.0;  // compass heading of travel (or of the optical axis if known)
  double s_m = 0.0;          // along-route distance
  // Rotation from camera to database ENU frame, when the positions carry orientation.
  std::optional<Eigen::Quaterniond> enu_from_cam;
  int num_features = 0;
};

// A triangulated 3-D point of the survey (schema version 3).
struct DbPoint3d {
  int64_t point_id = -1;                                        // set by WritePoint
  Eigen::Vector3d position_in_enu = Eigen::Vector3d::Zero();  // database ENU frame, metres
  double error_px = 0.0;          // RMS reprojection error over its observations, pixels
  int num_observations = 0;       // >= 2
};

// One observation of a point by a feature of a database frame.
struct DbObservation {
  image_t image_id = kInvalidImage;
  int feature_index = -1;  // row of the frame's keypoints / descriptors
};

// The points a database frame sees, by feature (ReadFramePoints).
struct DbFramePoint {
  int feature_index = -1;
  int64_t point_id = -1;
  Eigen::Vector3d position_in_enu = Eigen::Vector3d::Zero();
};

// One connection; use a Database from one thread at a time (its prepared
// statements are shared).
class Database {
 public:
  // The schema version this build writes (number of the last migration in db_schema/).
  static int LatestSchemaVersion();

  enum class Mode { kReadWrite, kReadOnly };
  // Opens (kReadWrite: creates and migrates) the database. Throws Error naming the file if it is
  // not an SQLite database, is of a newer schema version than this build, is locked by another
  // writer (after a short busy timeout), or cannot be created. ":memory:" is allowed.
  explicit Database(const std::string& path, Mode mode = Mode::kReadWrite);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  const std::string& path() const { return path_; }
  int SchemaVersion() const;

  // Key-value metadata (created_by, ...).
  void SetMeta(const std::string& key, const std::string& value);
  std::optional<std::string> GetMeta(const std::string& key) const;

  // The ENU frame origin, set once by the first drive. Setting it again to the
  // same value is a no-op; to a different value throws Error (every stored ENU
  // position depends on it).
  std::optional<Geodetic> EnuOrigin() const;
  void SetEnuOrigin(const Geodetic& origin);

  camera_t WriteCamera(const DbCamera& camera);  // returns the new id
  DbCamera ReadCamera(camera_t camera_id) const;

  drive_t WriteDrive(const DbDrive& drive);  // returns the new id; name must be unique
  void UpdateDrive(const DbDrive& drive);    // by drive_id
  std::optional<DbDrive> FindDrive(const std::string& name) const;
  std::vector<DbDrive> ReadDrives() const;

  // Inserts a frame with its features atomically; throws if (drive_id, frame)
  // exists. The stored num_features is keypoints.rows(). Returns the id.
  image_t WriteFrame(const DbFrame& frame,
                     const FeatureKeypoints& keypoints,
                     const FeatureDescriptors& descriptors);
  bool HasFrame(drive_t drive_id, frame_t frame) const;
  DbFrame ReadFrame(image_t image_id) const;
  // Frames of one drive (or of all drives with kInvalidDrive), ordered by drive then timestamp.
  std::vector<DbFrame> ReadFrames(drive_t drive_id = kInvalidDrive) const;
  FeatureKeypoints ReadKeypoints(image_t image_id) const;
  FeatureDescriptors ReadDescriptors(image_t image_id) const;
  int64_t NumFrames(drive_t drive_id = kInvalidDrive) const;
  int64_t NumFeatures() const;

  // The route polyline (database ENU, metres), written once from the first drive.
  void WriteRoute(const std::vector<Eigen::Vector3d>& points_in_enu);
  std::vector<Eigen::Vector3d> ReadRoute() const;

  // Whole-image retrieval (schema version 2). The model is an opaque blob for this class
  // (GlobalDescriptorModel::Serialize); num_words and dims are stored beside it for inspection.
  // Writing replaces the one stored model.
  void WriteRetrievalModel(const std::vector<uint8_t>& data, int num_words, int dims);
  std::optional<std::vector<uint8_t>> ReadRetrievalModel() const;
  void DeleteRetrievalModel();
  // One global descriptor per frame (float32, little-endian); writing replaces the frame's
  // descriptor; it is deleted with its frame. Throws Error for an empty or non-finite descriptor
  // or an unknown image.
  void WriteGlobalDescriptor(image_t image_id, const std::vector<float>& descriptor);
  // All global descriptors, ordered by image_id. Throws Error naming the image for a blob whose
  // byte count is not 4 * dims.
  std::vector<std::pair<image_t, std::vector<float>>> ReadGlobalDescriptors() const;
  int64_t NumGlobalDescriptors() const;
  void ClearGlobalDescriptors();

  // Removal, for undoing a failed build: a frame (with its features); a drive (with its frames,
  // and its camera if no other drive uses it); the route and ENU origin (only sensible when no
  // drive remains).
  // Local 3-D structure (schema version 3). WritePoint stores a point with its observations (at
  // least 2, distinct frames, features seen by no other point) and returns its id; wrap many in a
  // Transaction. ReadFramePoints: the points frame `image_id` sees, by ascending feature_index
  // (Error for a negative index or non-finite position). ClearPoints: all points, observations.
  int64_t WritePoint(const DbPoint3d& point, const std::vector<DbObservation>& observations);
  std::vector<DbFramePoint> ReadFramePoints(image_t image_id) const;
  int64_t NumPoints() const;
  int64_t NumObservations() const;
  void ClearPoints();

  void DeleteFrame(image_t image_id);
  void DeleteDrive(drive_t drive_id);
  void ClearRouteAndOrigin();

  // A unit of work: commits on Commit(), rolls back when destroyed without it (also during an
  // exception). Not nestable.
  class Transaction {
   public:
    explicit Transaction(Database& database);
    ~Transaction();
    Transaction(const Transaction&) = delete;
    Transaction& operator=(const Transaction&) = delete;
    void Commit();

   private:
    Database& database_;
    bool done_ = false;
  };

 private:
  class Impl;
  std::string path_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace epiloc
