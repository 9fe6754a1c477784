#include "epiloc/anchor/structure_sift.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <set>

#include <spdlog/spdlog.h>

#include "epiloc/core/error.h"
#include "epiloc/db/database.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/position_readers.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// A scratch folder removed when it goes out of scope (also during an exception).
class ScratchDir {
 public:
  ScratchDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            fmt::format("epiloc-structure-{}-{}", static_cast<long>(getpid()), counter++);
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// Camera axes (x right, y down, z forward) in a level ENU frame looking north.
Eigen::Matrix3d LevelNorthFromCam() {
  Eigen::Matrix3d m;
  m << 1, 0, 0,  //
      0, 0, 1,   //
      0, -1, 0;
  return m;
}

// A point's first and last observing frame, their count and the rays' widest angle (first to last).
struct Seen {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  frame_t first = kInvalidFrame, last = kInvalidFrame;
  Eigen::Vector3d first_centre = Eigen::Vector3d::Zero(), last_centre = Eigen::Vector3d::Zero();
  int observations = 0;
  std::vector<VoObservation> seen;
};

constexpr double kMinSpreadM = 5.0;  // a shorter segment's scale would be the GNSS noise

// Metres per VO unit of a segment: the spread of the GNSS fixes at its poses over that of its VO
// centres (noise raises it by sigma^2 / spread^2: 2 % for 3 m over a 20 m spread; the
// triangulation's metric gates need no better); none when the fixes spread less than kMinSpreadM.
// `spread_m` gets the fixes' horizontal spread (RMS about their mean; 0 with fewer than two).
std::optional<double> GnssScale(const Drive& drive,
                                const EnuFrame& local,
                                const std::vector<const StampedPose*>& poses,
                                double* spread_m) {
  *spread_m = 0.0;
  std::vector<Eigen::Vector3d> gnss, centres;
  for (const StampedPose* pose : poses) {
    const auto fix = drive.gnss.Interpolate(pose->timestamp_s, drive.max_gap_s);
    if (!fix) continue;
    gnss.push_back(local.ToEnu(fix->position));
    centres.push_back(pose->world_from_cam.translation);
  }
  if (gnss.size() < 2) return std::nullopt;
  Eigen::Vector3d gm = Eigen::Vector3d::Zero(), vm = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < gnss.size(); ++i) {
    gm += gnss[i];
    vm += centres[i];
  }
  gm /= static_cast<double>(gnss.size());
  vm /= static_cast<double>(centres.size());
  double g2 = 0.0, v2 = 0.0;
  for (size_t i = 0; i < gnss.size(); ++i) {
    g2 += (gnss[i] - gm).head<2>().squaredNorm();
    v2 += (centres[i] - vm).squaredNorm();
  }
  *spread_m = std::sqrt(g2 / gnss.size());
  if (*spread_m < kMinSpreadM || v2 <= 0.0) return std::nullopt;
  return std::sqrt(g2 / v2);
}

}  // namespace

VoStructure TriangulateAlongVo(const std::string& drive_dir,
                               const VoStructure& vo,
                               const BuildDbOptions& build,
                               SiftStructureSummary* summary,
                               const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  const Drive drive = LoadDrive(drive_dir);
  if (drive.gnss.samples.empty()) Throw("{}: the drive has no GNSS positions", drive.dir);
  const EnuFrame local(drive.gnss.samples.front().position);
  SiftStructureSummary sums;

  // Poses on the drive's frames, by segment.
  const VoStructure timed = vo.OnFramesOf(drive);
  std::map<int, std::vector<const StampedPose*>> by_segment;
  for (const StampedPose& pose : timed.poses) {
    if (pose.frame == kInvalidFrame) continue;
    const int segment = vo.SegmentOf(pose.frame);
    if (segment >= 0) by_segment[segment].push_back(&pose);
  }

  VoStructure out = vo;
  out.points.clear();
  std::set<int> replaced;
  double track_length_sum = 0.0;
  for (const auto& [segment, poses] : by_segment) {
    if (poses.size() < 2) continue;
    double spread_m = 0.0;
    const std::optional<double> scale = GnssScale(drive, local, poses, &spread_m);
    if (!scale) {
      spdlog::info(
          "VO segment {} (frames {}..{}): its GNSS fixes spread {:.1f} m (RMS), below the {} m "
          "that give the SIFT structure a scale (a shorter drive's would be the fixes' noise): "
          "no SIFT points, its VO points kept",
          segment, poses.front()->frame, poses.back()->frame, spread_m, kMinSpreadM);
      continue;
    }
    const Eigen::Matrix3d level =
        LevelNorthFromCam() * poses.front()->world_from_cam.rotation.conjugate().toRotationMatrix();
    const Eigen::Vector3d first = poses.front()->world_from_cam.translation;

    PositionTrack track;
    track.source = fmt::format("VO segment {}", segment);
    for (const StampedPose* pose : poses) {
      PositionSample sample;
      sample.timestamp_s = pose->timestamp_s;
      sample.position =
          local.ToGeodetic(*scale * (level * (pose->world_from_cam.translation - first)));
      sample.enu_from_cam =
          Eigen::Quaterniond(level * pose->world_from_cam.rotation.toRotationMatrix()).normalized();
      sample.frame = pose->frame;
      track.samples.push_back(sample);
    }
    const ScratchDir scratch;
    const std::string positions = (scratch.path() / "positions.csv").string();
    const std::string db_path = (scratch.path() / "structure.sqlite").string();
    WritePositionCsv(track, positions);
    BuildDbOptions options = build;
    options.positions = positions;
    options.retrieval_index = false;
    options.triangulate = true;
    const BuildDbSummary built = BuildDatabase(drive_dir, db_path, options, progress);
    track_length_sum += built.triangulation.mean_track_length * built.triangulation.num_points;

    // The points, back in the VO world: x_vo = level^T x / scale + first.
    Database db(db_path, Database::Mode::kReadOnly);
    const EnuFrame db_enu(*db.EnuOrigin());
    const auto to_vo = [&](const Eigen::Vector3d& in_db) {
      const Eigen::Vector3d x = local.ToEnu(db_enu.ToGeodetic(in_db));
      return Eigen::Vector3d(level.transpose() * x / *scale + first);
    };
    std::map<int64_t, Seen> seen;
    std::map<drive_t, Camera> cameras;
    for (const DbDrive& d : db.ReadDrives())
      cameras[d.drive_id] = db.ReadCamera(d.camera_id).camera;
    for (const DbFrame& frame : db.ReadFrames()) {
      ++sums.frames;
      const Eigen::Vector3d centre = to_vo(frame.center_in_enu);
      const Camera& camera = cameras.at(frame.drive_id);
      out.observation_focal_px = camera.fx;
      const FeatureKeypoints keypoints = db.ReadKeypoints(frame.image_id);
      for (const DbFramePoint& p : db.ReadFramePoints(frame.image_id)) {
        Seen& s = seen[p.point_id];
        if (p.feature_index >= 0 && p.feature_index < keypoints.rows()) {
          VoObservation o;
          o.frame = frame.frame;
          o.normalized =
              camera.Unproject(keypoints.row(p.feature_index).head<2>().transpose().cast<double>());
          s.seen.push_back(o);
        }
        if (s.observations == 0) {
          s.position = to_vo(p.position_in_enu);
          s.first = frame.frame;
          s.first_centre = centre;
        }
        s.last = frame.frame;
        s.last_centre = centre;
        ++s.observations;
      }
    }
    for (auto& [id, s] : seen) {
      VoPoint point;
      point.point_in_world = s.position;
      point.segment = segment;
      point.first_frame = s.first;
      point.last_frame = s.last;
      point.observations = s.observations;
      point.parallax_deg = ParallaxDeg(s.position, s.first_centre, s.last_centre);
      point.seen = std::move(s.seen);
      out.points.push_back(point);
    }
    sums.points += static_cast<int64_t>(seen.size());
    ++sums.segments;
    replaced.insert(segment);
  }
  // Segments not triangulated keep the VO's own points.
  for (const VoPoint& p : vo.points) {
    if (!replaced.count(p.segment)) out.points.push_back(p);
  }
  sums.mean_track_length = sums.points > 0 ? track_length_sum / sums.points : 0.0;
  sums.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) *summary = sums;
  return out;
}

}  // namespace epiloc
