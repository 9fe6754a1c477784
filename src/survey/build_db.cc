#include "epiloc/survey/build_db.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/ranges.h>
#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include "epiloc/camera/undistorter.h"
#include "epiloc/core/error.h"
#include "epiloc/core/hash.h"
#include "epiloc/db/database.h"
#include "epiloc/geo/route.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/io/position_readers.h"
#include "epiloc/survey/retrieval_index.h"

namespace epiloc {
namespace {

// Frames without features warned about one by one; the summary at the end counts them all.
constexpr int kFeaturelessWarnings = 3;

struct FrameJob {
  size_t frame_index = 0;  // index into Drive::frames
  PositionSample position;
};

struct FrameResult {
  DbFrame frame;
  FeatureSet features;
};

// Restores OpenCV's thread count when the build ends: frame-level parallelism replaces OpenCV's
// own, which would oversubscribe the cores.
class ScopedOpenCvThreads {
 public:
  explicit ScopedOpenCvThreads(int num_threads) : previous_(cv::getNumThreads()) {
    cv::setNumThreads(num_threads);
  }
  ~ScopedOpenCvThreads() { cv::setNumThreads(previous_); }

 private:
  int previous_;
};

// The route through `points`; its errors name the database and the positions' file.
Route RouteOf(const std::vector<Eigen::Vector3d>& points,
              const std::string& db_path,
              const std::string& positions_source) {
  try {
    return Route(points);
  } catch (const Error& e) {
    Throw("{}: {} (positions from {})", db_path, e.what(), positions_source);
  }
}

// Resolves "auto" to the source it picks, so the database records what was used.
std::string ResolvePositionChoice(const Drive& drive, const std::string& choice) {
  if (choice != "auto") return choice;
  if (drive.ground_truth && !drive.ground_truth->samples.empty()) return "ground_truth";
  if (!drive.gnss.samples.empty()) return "gnss";
  Throw("{}: the drive has neither ground truth nor GNSS positions", drive.dir);
}

PositionTrack SelectPositions(const Drive& drive, const std::string& choice) {
  if (choice == "ground_truth") {
    if (!drive.ground_truth || drive.ground_truth->samples.empty()) {
      Throw("{}: the drive has no ground truth positions", drive.dir);
    }
    return *drive.ground_truth;
  }
  if (choice == "gnss") {
    if (drive.gnss.samples.empty()) Throw("{}: the drive has no GNSS positions", drive.dir);
    return drive.gnss;
  }
  return ReadPositionCsv(choice, std::nullopt);
}

DbCamera CameraRecord(const Undistorter& undistorter) {
  DbCamera camera;
  camera.camera = undistorter.undistorted_camera();
  camera.original = undistorter.distorted_camera();
  return camera;
}

// The drive's row: found (resume / re-run) or created. A drive of the same name built from a
// different camera is refused rather than mixed.
DbDrive EnsureDrive(Database& db,
                    const Drive& drive,
                    const DbCamera& camera,
                    const std::string& positions,
                    int64_t num_planned) {
  if (std::optional<DbDrive> existing = db.FindDrive(drive.name)) {
    const DbCamera stored = db.ReadCamera(existing->camera_id);
    if (!(stored.original == camera.original)) {
      Throw("{}: drive '{}' is already in the database with another camera calibration",
            db.path(), drive.name);
    }
    existing->num_frames_planned = num_planned;
    existing->complete = false;  // set again when this run has added every planned frame
    existing->positions = positions;
    db.UpdateDrive(*existing);
    return *existing;
  }
  DbDrive record;
  record.name = drive.name;
  record.source_dir = drive.dir;
  record.camera_id = db.WriteCamera(camera);
  record.positions = positions;
  record.num_frames_planned = num_planned;
  record.drive_id = db.WriteDrive(record);
  return record;
}

double HeadingDeg(const DbFrame& frame, const Route& route) {
  if (frame.enu_from_cam) {
    const Eigen::Vector3d axis = *frame.enu_from_cam * Eigen::Vector3d::UnitZ();
    if (axis.head<2>().norm() > 1e-6) return CompassHeadingFromEnuDirection(axis.head<2>());
  }
  return CompassHeadingFromEnuDirection(route.DirectionAt(frame.s_m).head<2>());
}

// Removes what a failed run added: its frames, the drive row if it created it (else restores the
// row as it was), and the origin and route if it set them. One transaction; a failure to undo is
// logged, and the original error is what the caller sees.
void UndoBuild(Database& db,
               const DbDrive& drive_record,
               const std::optional<DbDrive>& previous_record,
               bool created_origin,
               const std::vector<image_t>& added_images) {
  try {
    Database::Transaction transaction(db);
    for (const image_t image_id : added_images) db.DeleteFrame(image_id);
    if (previous_record) {
      db.UpdateDrive(*previous_record);
    } else if (drive_record.drive_id != kInvalidDrive) {
      db.DeleteDrive(drive_record.drive_id);
    }
    if (created_origin) db.ClearRouteAndOrigin();
    transaction.Commit();
    spdlog::info("{}: build stopped, the {} frames added by this run were removed", db.path(),
                 added_images.size());
  } catch (const std::exception& e) {
    spdlog::error("{}: could not undo the failed build: {}", db.path(), e.what());
  }
}

// Creates the database file when it does not exist yet and, if this run created it, removes it
// with its -wal, -shm and -journal when the run fails, so a failed first build leaves nothing
// behind. Declared before the Database, so it runs after the connection has closed. Creating the
// file exclusively here (an empty file is an empty SQLite database) decides which of two
// concurrent first builds created it. A file another process opened meanwhile stays: its
// connection keeps <db>-wal (the last connection to close removes it), and deleting files under
// an open database would lose that process's work.
class NewDatabaseFile {
 public:
  explicit NewDatabaseFile(const std::string& path)
      : path_(path), exceptions_(std::uncaught_exceptions()) {
    if (path.empty() || path == ":memory:") return;
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    // EEXIST: a database to add to; other errors are SQLite's to report when it opens the file.
    if (fd >= 0) {
      ::close(fd);
      created_ = true;
    }
  }
  ~NewDatabaseFile() {
    if (!created_ || std::uncaught_exceptions() <= exceptions_) return;
    std::error_code error;
    if (std::filesystem::exists(path_ + "-wal", error)) {
      spdlog::warn("{}: another process opened the new database; it is left in place", path_);
      return;
    }
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) {
      std::filesystem::remove(path_ + suffix, error);
    }
  }
  NewDatabaseFile(const NewDatabaseFile&) = delete;
  NewDatabaseFile& operator=(const NewDatabaseFile&) = delete;

 private:
  std::string path_;
  int exceptions_;
  bool created_ = false;
};

}  // namespace

void BuildDbOptions::Check() const {
  EPILOC_CHECK(!positions.empty(), "build-db: --positions must not be empty");
  EPILOC_CHECK(num_threads >= 0, "build-db: --threads must be >= 0, got {}", num_threads);
  sift.Check();
  if (triangulate) triangulation.Check();
}

BuildDbSummary BuildDatabase(const std::string& drive_dir,
                             const std::string& db_path,
                             const BuildDbOptions& options,
                             const ProgressCallback& progress) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  const Drive drive = LoadDrive(drive_dir);
  const std::string position_source = ResolvePositionChoice(drive, options.positions);
  const PositionTrack track = SelectPositions(drive, position_source);
  const FramePositions positions = PositionFrames(drive, track);

  BuildDbSummary summary;
  summary.drive_name = drive.name;
  summary.frames_in_drive = static_cast<int64_t>(drive.frames.size());
  summary.frames_without_position = static_cast<int64_t>(positions.missing.size());

  std::vector<FrameJob> positioned;
  for (size_t i = 0; i < drive.frames.size(); ++i) {
    if (positions.per_frame[i]) positioned.push_back({i, *positions.per_frame[i]});
  }
  EPILOC_CHECK(positioned.size() >= 2, "{}: only {} frames have a position within {} s",
               drive.dir, positioned.size(), drive.max_gap_s);

  const Undistorter undistorter(drive.camera);
  const FrameReader reader(drive);
  const NewDatabaseFile new_file(db_path);
  Database db(db_path);

  // Set-up is one unit of work: origin, route, camera and drive rows appear together or not at all.
  DbDrive drive_record;
  std::optional<EnuFrame> enu;
  std::vector<Eigen::Vector3d> route_points;
  // What this run changed, so bad input found half-way leaves the database as it was.
  const std::optional<DbDrive> previous_record = db.FindDrive(drive.name);
  bool created_origin = false;
  std::vector<image_t> added_images;
  {
    Database::Transaction transaction(db);
    std::optional<Geodetic> origin = db.EnuOrigin();
    if (!origin) {
      created_origin = true;
      origin = positioned.front().position.position;
      db.SetEnuOrigin(*origin);
    }
    enu.emplace(*origin);
    route_points = db.ReadRoute();
    if (route_points.empty()) {
      for (const FrameJob& job : positioned) route_points.push_back(enu->ToEnu(job.position.position));
      db.WriteRoute(RouteOf(route_points, db_path, track.source).points());
      route_points = db.ReadRoute();
    }
    drive_record = EnsureDrive(db, drive, CameraRecord(undistorter), position_source,
                               static_cast<int64_t>(positioned.size()));
    transaction.Commit();
  }
  const Route route = RouteOf(route_points, db_path, track.source);
  summary.drive_id = drive_record.drive_id;
  summary.route_length_m = route.length_m();

  std::vector<FrameJob> todo;
  for (const FrameJob& job : positioned) {
    if (db.HasFrame(drive_record.drive_id, drive.frames[job.frame_index].frame)) {
      ++summary.frames_already_present;
    } else {
      todo.push_back(job);
    }
  }
  if (summary.frames_already_present > 0) {
    spdlog::info("drive '{}': {} frames already in {}, {} to add", drive.name,
                 summary.frames_already_present, db_path, todo.size());
  }

  const int num_threads = options.num_threads > 0
                              ? options.num_threads
                              : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  ScopedOpenCvThreads opencv_threads(1);

  // Workers extract in any order; the writer commits in drive order, one transaction per frame.
  // At most max_in_flight results wait in memory.
  const size_t max_in_flight = 2 * static_cast<size_t>(num_threads) + 2;
  std::atomic<size_t> next_job{0};
  std::mutex mutex;
  std::condition_variable changed;
  std::map<size_t, FrameResult> ready;
  size_t num_written = 0;
  bool stop = false;
  bool another_build = false;  // the drive's row and the route now belong to that build too
  std::exception_ptr failure;

  auto work = [&]() {
    while (true) {
      const size_t k = next_job.fetch_add(1);
      if (k >= todo.size()) return;
      {
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [&] { return stop || k < num_written + max_in_flight; });
        if (stop) return;
      }
      try {
        const FrameJob& job = todo[k];
        const FrameRecord& record = drive.frames[job.frame_index];
        const cv::Mat image = reader.ReadGrey(job.frame_index);
        FrameResult result;
        result.features = ExtractSift(undistorter.Undistort(image), options.sift);
        DbFrame& frame = result.frame;
        frame.drive_id = drive_record.drive_id;
        frame.frame = record.frame;
        frame.timestamp_s = record.timestamp_s;
        if (record.image.empty()) {
          frame.image_hash = HashBytes(image.data, image.total() * image.elemSize());
        } else {
          frame.image_path = drive.ImagePath(record);
          frame.image_hash = HashFile(frame.image_path);
        }
        frame.position = job.position.position;
        frame.center_in_enu = enu->ToEnu(frame.position);
        if (job.position.enu_from_cam) {
          frame.enu_from_cam = Eigen::Quaterniond(enu->EnuFromLocalEnu(frame.position) *
                                                  job.position.enu_from_cam->toRotationMatrix())
                                   .normalized();
        }
        frame.s_m = route.Project(frame.center_in_enu).s_m;
        frame.heading_deg = HeadingDeg(frame, route);
        frame.num_features = result.features.size();
        std::lock_guard<std::mutex> lock(mutex);
        ready.emplace(k, std::move(result));
        changed.notify_all();
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!failure) failure = std::current_exception();
        stop = true;
        changed.notify_all();
        return;
      }
    }
  };

  std::vector<std::thread> workers;
  for (int i = 0; i < num_threads; ++i) workers.emplace_back(work);

  try {
    for (size_t k = 0; k < todo.size(); ++k) {
      FrameResult result;
      {
        std::unique_lock<std::mutex> lock(mutex);
        changed.wait(lock, [&] { return stop || ready.count(k) > 0; });
        if (ready.count(k) == 0) break;  // a worker failed
        result = std::move(ready.at(k));
        ready.erase(k);
      }
      if (db.HasFrame(drive_record.drive_id, result.frame.frame)) {
        // Not there when this run listed its work: another process is adding the same frames.
        another_build = true;
        Throw("{}: another build of drive '{}' is running on this database (it added frame {} "
              "meanwhile); let it finish",
              db_path, drive.name, result.frame.frame);
      }
      {
        Database::Transaction transaction(db);
        added_images.push_back(
            db.WriteFrame(result.frame, result.features.keypoints, result.features.descriptors));
        transaction.Commit();
      }
      summary.frames_added += 1;
      summary.features_added += result.features.size();
      if (result.features.size() == 0) {
        std::vector<frame_t>& none = summary.frames_without_features;
        none.push_back(result.frame.frame);
        if (none.size() <= static_cast<size_t>(kFeaturelessWarnings)) {
          const std::string where = drive.FrameWhere(drive.frames[todo[k].frame_index]);
          spdlog::warn(
              "{}frame {} gave no SIFT features (a black, overexposed or textureless "
              "image){}",
              where.empty() ? "" : where + ": ", result.frame.frame,
              none.size() == static_cast<size_t>(kFeaturelessWarnings)
                  ? "; further ones are counted at the end"
                  : "");
        }
      }
      {
        std::lock_guard<std::mutex> lock(mutex);
        num_written = k + 1;
        changed.notify_all();
      }
      if (progress) {
        progress(summary.frames_already_present + summary.frames_added,
                 static_cast<int64_t>(positioned.size()));
      }
    }
  } catch (...) {
    std::lock_guard<std::mutex> lock(mutex);
    if (!failure) failure = std::current_exception();
    stop = true;
    changed.notify_all();
  }
  for (std::thread& worker : workers) worker.join();
  if (failure) {
    if (another_build) {
      UndoBuild(db, drive_record, db.FindDrive(drive.name), false, added_images);
    } else {
      UndoBuild(db, drive_record, previous_record, created_origin, added_images);
    }
    std::rethrow_exception(failure);
  }

  if (!summary.frames_without_features.empty()) {
    const auto& none = summary.frames_without_features;
    spdlog::warn("drive '{}': {} of {} frames gave no SIFT features (frames {}{}): black, "
                 "overexposed or textureless images; nothing can be localized against them",
                 drive.name, none.size(), summary.frames_added,
                 fmt::join(none.begin(), none.begin() + std::min<size_t>(none.size(), 5), ", "),
                 none.size() > 5 ? ", ..." : "");
  }
  {
    Database::Transaction transaction(db);
    drive_record.complete = true;
    db.UpdateDrive(drive_record);
    transaction.Commit();
  }
  if (options.retrieval_index && (summary.frames_added > 0 || !HasCurrentRetrievalIndex(db))) {
    const RetrievalIndexSummary index = BuildRetrievalIndex(db, VocabularyOptions());
    if (!index.built) spdlog::warn("{}: no retrieval index: {}", db_path, index.reason);
  }
  if (options.triangulate && (summary.frames_added > 0 || db.NumPoints() == 0)) {
    TriangulateOptions triangulation = options.triangulation;
    if (triangulation.num_threads == 0) triangulation.num_threads = num_threads;
    summary.triangulation = TriangulateDatabase(db, triangulation);
    summary.triangulated = true;
  }
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace epiloc
