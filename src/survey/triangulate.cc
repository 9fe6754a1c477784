#include "epiloc/survey/triangulate.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <numeric>
#include <thread>
#include <utility>

#include <spdlog/spdlog.h>
#include <Eigen/Dense>

#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"
#include "epiloc/db/database.h"

namespace epiloc {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Disjoint sets over (frame, feature) nodes with path halving.
class UnionFind {
 public:
  explicit UnionFind(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  size_t Find(size_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void Union(size_t a, size_t b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<size_t> parent_;
};

struct Residual {
  double squared_px = 0.0;  // squared pixel reprojection error
  bool in_range = false;    // depth within the options' range
};

// The reprojection residual of `point` in one observation.
Residual ReprojectionResidual(const TrackObservation& observation,
                              const Eigen::Vector3d& point,
                              const Camera& camera,
                              const TriangulateOptions& options) {
  const Eigen::Vector3d p = observation.cam_from_world * point;
  Residual residual;
  residual.in_range = p.z() >= options.min_depth_m && p.z() <= options.max_depth_m;
  if (p.z() <= 0.0) {
    residual.squared_px = std::numeric_limits<double>::infinity();
    return residual;
  }
  const Eigen::Vector2d pixel(camera.fx * p.x() / p.z() + camera.cx,
                              camera.fy * p.y() / p.z() + camera.cy);
  residual.squared_px = (pixel - observation.pixel).squaredNorm();
  return residual;
}

// Linear triangulation (DLT on normalised coordinates) of the kept observations.
bool TriangulateDlt(const std::vector<TrackObservation>& observations,
                    const std::vector<char>& keep,
                    const Camera& camera,
                    Eigen::Vector3d& point) {
  const int n = static_cast<int>(std::count(keep.begin(), keep.end(), 1));
  Eigen::MatrixXd a(2 * n, 4);
  int row = 0;
  for (size_t k = 0; k < observations.size(); ++k) {
    if (!keep[k]) continue;
    Eigen::Matrix<double, 3, 4> projection;
    projection.leftCols<3>() = observations[k].cam_from_world.rotation.toRotationMatrix();
    projection.col(3) = observations[k].cam_from_world.translation;
    const double u = (observations[k].pixel.x() - camera.cx) / camera.fx;
    const double v = (observations[k].pixel.y() - camera.cy) / camera.fy;
    a.row(row++) = u * projection.row(2) - projection.row(0);
    a.row(row++) = v * projection.row(2) - projection.row(1);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d x = svd.matrixV().col(3);
  if (std::abs(x(3)) < 1e-12 * x.head<3>().norm()) return false;  // at infinity
  point = x.head<3>() / x(3);
  return point.allFinite();
}

// Gauss-Newton on the pixel reprojection error of the kept observations, from `point`.
void RefinePoint(const std::vector<TrackObservation>& observations,
                 const std::vector<char>& keep,
                 const Camera& camera,
                 Eigen::Vector3d& point) {
  auto cost = [&](const Eigen::Vector3d& x) {
    double sum = 0.0;
    for (size_t k = 0; k < observations.size(); ++k) {
      if (!keep[k]) continue;
      const Eigen::Vector3d p = observations[k].cam_from_world * x;
      if (p.z() <= 0.0) return std::numeric_limits<double>::infinity();
      const Eigen::Vector2d pixel(camera.fx * p.x() / p.z() + camera.cx,
                                  camera.fy * p.y() / p.z() + camera.cy);
      sum += (pixel - observations[k].pixel).squaredNorm();
    }
    return sum;
  };
  double current = cost(point);
  if (!std::isfinite(current)) return;
  for (int iteration = 0; iteration < 10; ++iteration) {
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
    for (size_t k = 0; k < observations.size(); ++k) {
      if (!keep[k]) continue;
      const Eigen::Matrix3d r = observations[k].cam_from_world.rotation.toRotationMatrix();
      const Eigen::Vector3d p = r * point + observations[k].cam_from_world.translation;
      const double iz = 1.0 / p.z();
      Eigen::Matrix<double, 2, 3> d_pixel_d_p;
      d_pixel_d_p << camera.fx * iz, 0.0, -camera.fx * p.x() * iz * iz,  //
          0.0, camera.fy * iz, -camera.fy * p.y() * iz * iz;
      const Eigen::Matrix<double, 2, 3> j = d_pixel_d_p * r;
      const Eigen::Vector2d e(camera.fx * p.x() * iz + camera.cx - observations[k].pixel.x(),
                              camera.fy * p.y() * iz + camera.cy - observations[k].pixel.y());
      jtj += j.transpose() * j;
      jtr += j.transpose() * e;
    }
    const Eigen::Vector3d step = jtj.ldlt().solve(-jtr);
    if (!step.allFinite()) return;
    const Eigen::Vector3d candidate = point + step;
    const double next = cost(candidate);
    if (!(next < current)) return;
    point = candidate;
    const bool converged = step.norm() < 1e-12 * (1.0 + point.norm()) || current - next < 1e-14;
    current = next;
    if (converged) return;
  }
}

// Fundamental matrix F with x_b^T F x_a = 0 for pixels of the same camera at two poses.
Eigen::Matrix3d FundamentalMatrix(const Rigid3d& a_from_world,
                                  const Rigid3d& b_from_world,
                                  const Camera& camera) {
  const Rigid3d b_from_a = b_from_world * a_from_world.Inverse();
  const Eigen::Vector3d& t = b_from_a.translation;
  Eigen::Matrix3d t_cross;
  t_cross << 0.0, -t.z(), t.y(), t.z(), 0.0, -t.x(), -t.y(), t.x(), 0.0;
  const Eigen::Matrix3d essential = t_cross * b_from_a.rotation.toRotationMatrix();
  const Eigen::Matrix3d k_inv = camera.K().inverse();
  return k_inv.transpose() * essential * k_inv;
}

// Larger of the two point-to-epipolar-line distances, pixels.
double EpipolarError(const Eigen::Matrix3d& f,
                     const Eigen::Vector2d& pixel_a,
                     const Eigen::Vector2d& pixel_b) {
  const Eigen::Vector3d xa = pixel_a.homogeneous();
  const Eigen::Vector3d xb = pixel_b.homogeneous();
  const Eigen::Vector3d line_b = f * xa;
  const Eigen::Vector3d line_a = f.transpose() * xb;
  const double algebraic = std::abs(xb.dot(line_b));
  return std::max(algebraic / line_b.head<2>().norm(), algebraic / line_a.head<2>().norm());
}

struct OrientedFrame {
  image_t image_id = kInvalidImage;
  Rigid3d cam_from_local;  // local: the drive's ENU shifted to `reference`
  Eigen::Vector3d center_in_local = Eigen::Vector3d::Zero();
};

struct PointRecord {
  DbPoint3d point;
  std::vector<DbObservation> observations;
};

// Everything of one drive: matching, tracks, triangulation. Appends to `points`.
void TriangulateDrive(Database& db,
                      const DbDrive& drive,
                      const std::vector<DbFrame>& frames,
                      const TriangulateOptions& options,
                      int num_threads,
                      const std::function<void(int64_t)>& frames_done,
                      TriangulateSummary& summary,
                      std::vector<PointRecord>& points) {
  const auto drive_start = std::chrono::steady_clock::now();
  const Camera camera = db.ReadCamera(drive.camera_id).camera;
  const Eigen::Vector3d reference = frames.front().center_in_enu;
  std::vector<OrientedFrame> oriented(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    oriented[i].image_id = frames[i].image_id;
    oriented[i].center_in_local = frames[i].center_in_enu - reference;
    const Eigen::Quaterniond cam_from_enu = frames[i].enu_from_cam->conjugate().normalized();
    oriented[i].cam_from_local =
        Rigid3d(cam_from_enu, -(cam_from_enu * oriented[i].center_in_local));
  }

  // Neighbours: the next frames with a baseline in range (frames of a stop are passed over).
  std::vector<std::vector<size_t>> neighbours(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    for (size_t j = i + 1; j < frames.size(); ++j) {
      const double baseline = (oriented[j].center_in_local - oriented[i].center_in_local).norm();
      if (baseline > options.max_baseline_m) break;
      if (baseline < options.min_baseline_m) continue;
      neighbours[i].push_back(j);
      if (static_cast<int>(neighbours[i].size()) >= options.num_neighbours) break;
    }
  }

  std::vector<FeatureKeypoints> keypoints(frames.size());
  std::vector<size_t> node_offset(frames.size() + 1, 0);
  for (size_t i = 0; i < frames.size(); ++i) {
    keypoints[i] = db.ReadKeypoints(frames[i].image_id);
    if (options.max_features > 0 && keypoints[i].rows() > options.max_features) {
      keypoints[i].conservativeResize(options.max_features, Eigen::NoChange);
    }
    node_offset[i + 1] = node_offset[i] + static_cast<size_t>(keypoints[i].rows());
  }
  const int max_rows = options.max_features > 0 ? options.max_features : -1;

  // Matching in blocks of frames, so only the descriptors of one block and its neighbours are in
  // memory (the database is read from this thread only).
  UnionFind tracks(node_offset.back());
  std::vector<char> matched(node_offset.back(), 0);
  std::map<size_t, FeatureDescriptors> descriptors;
  const size_t block_size = static_cast<size_t>(std::max(8, 4 * num_threads));
  for (size_t begin = 0; begin < frames.size(); begin += block_size) {
    const size_t end = std::min(frames.size(), begin + block_size);
    for (size_t i = begin; i < end; ++i) {
      std::vector<size_t> needed = neighbours[i];
      if (!needed.empty()) needed.push_back(i);
      for (const size_t k : needed) {
        if (descriptors.count(k) == 0)
          descriptors.emplace(k, db.ReadDescriptors(frames[k].image_id));
      }
    }
    std::vector<std::vector<std::pair<size_t, size_t>>> links(end - begin);
    std::vector<int64_t> pair_matches(end - begin, 0);
    ParallelFor(static_cast<int64_t>(end - begin), num_threads, [&](int64_t b) {
      const size_t i = begin + b;
      if (neighbours[i].empty()) return;
      const DescriptorIndex index(descriptors.at(i), options.matching, max_rows);
      for (const size_t j : neighbours[i]) {
        const Eigen::Matrix3d f =
            FundamentalMatrix(oriented[i].cam_from_local, oriented[j].cam_from_local, camera);
        for (const FeatureMatch& match : index.Match(descriptors.at(j), max_rows)) {
          ++pair_matches[b];
          const Eigen::Vector2d pixel_i =
              keypoints[i].row(match.index_a).head<2>().transpose().cast<double>();
          const Eigen::Vector2d pixel_j =
              keypoints[j].row(match.index_b).head<2>().transpose().cast<double>();
          if (EpipolarError(f, pixel_i, pixel_j) > options.max_epipolar_error_px) continue;
          links[b].emplace_back(node_offset[i] + match.index_a, node_offset[j] + match.index_b);
        }
      }
    });
    for (size_t b = 0; b < links.size(); ++b) {
      summary.num_pairs += static_cast<int64_t>(neighbours[begin + b].size());
      summary.num_matches += pair_matches[b];
      summary.num_epipolar_inliers += static_cast<int64_t>(links[b].size());
      for (const auto& [a, c] : links[b]) {
        tracks.Union(a, c);
        matched[a] = matched[c] = 1;
      }
    }
    descriptors.erase(descriptors.begin(), descriptors.lower_bound(end));
    frames_done(static_cast<int64_t>(end - begin));
  }

  const auto matched_time = std::chrono::steady_clock::now();
  // Tracks: nodes grouped by root; one frame seen twice means a wrong match somewhere, dropped.
  std::vector<std::pair<size_t, size_t>> root_node;
  for (size_t node = 0; node < matched.size(); ++node) {
    if (matched[node]) root_node.emplace_back(tracks.Find(node), node);
  }
  std::sort(root_node.begin(), root_node.end());
  std::vector<std::vector<std::pair<size_t, int>>> track_list;  // (frame, feature)
  for (size_t k = 0; k < root_node.size();) {
    size_t end = k;
    std::vector<std::pair<size_t, int>> track;
    bool repeated = false;
    while (end < root_node.size() && root_node[end].first == root_node[k].first) {
      const size_t node = root_node[end].second;
      const size_t frame =
          static_cast<size_t>(std::upper_bound(node_offset.begin(), node_offset.end(), node) -
                              node_offset.begin()) -
          1;
      if (!track.empty() && track.back().first == frame) repeated = true;  // nodes sorted
      track.emplace_back(frame, static_cast<int>(node - node_offset[frame]));
      ++end;
    }
    k = end;
    if (!repeated && track.size() >= 2) track_list.push_back(std::move(track));
  }
  summary.num_tracks += static_cast<int64_t>(track_list.size());

  std::vector<TrackTriangulation> results(track_list.size());
  ParallelFor(static_cast<int64_t>(track_list.size()), num_threads, [&](int64_t t) {
    std::vector<TrackObservation> observations;
    observations.reserve(track_list[t].size());
    for (const auto& [frame, feature] : track_list[t]) {
      observations.push_back({oriented[frame].cam_from_local,
                              keypoints[frame].row(feature).head<2>().transpose().cast<double>()});
    }
    results[t] = TriangulateTrack(observations, camera, options);
  });
  spdlog::debug(
      "drive '{}': matching {:.2f} s, tracks and triangulation {:.2f} s", drive.name,
      std::chrono::duration<double>(matched_time - drive_start).count(),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - matched_time).count());
  for (size_t t = 0; t < track_list.size(); ++t) {
    if (!results[t].valid) continue;
    PointRecord record;
    record.point.position_in_enu = results[t].point_in_world + reference;
    record.point.error_px = results[t].rms_error_px;
    for (size_t k = 0; k < track_list[t].size(); ++k) {
      if (!results[t].inlier_mask[k]) continue;
      record.observations.push_back(
          {oriented[track_list[t][k].first].image_id, track_list[t][k].second});
    }
    record.point.num_observations = static_cast<int>(record.observations.size());
    points.push_back(std::move(record));
  }
}

}  // namespace

void TriangulateOptions::Check() const {
  EPILOC_CHECK(num_neighbours >= 1, "triangulate: num_neighbours must be >= 1, got {}",
               num_neighbours);
  EPILOC_CHECK(min_baseline_m >= 0.0 && max_baseline_m > min_baseline_m,
               "triangulate: need 0 <= min_baseline_m < max_baseline_m, got {} and {}",
               min_baseline_m, max_baseline_m);
  EPILOC_CHECK(max_features >= 0, "triangulate: max_features must be >= 0, got {}", max_features);
  matching.Check();
  EPILOC_CHECK(max_epipolar_error_px > 0.0,
               "triangulate: max_epipolar_error_px must be > 0, got {}", max_epipolar_error_px);
  EPILOC_CHECK(max_reprojection_error_px > 0.0,
               "triangulate: max_reprojection_error_px must be > 0, got {}",
               max_reprojection_error_px);
  EPILOC_CHECK(min_triangulation_angle_deg >= 0.0 && min_triangulation_angle_deg < 90.0,
               "triangulate: min_triangulation_angle_deg must be in [0, 90), got {}",
               min_triangulation_angle_deg);
  EPILOC_CHECK(min_depth_m > 0.0 && max_depth_m > min_depth_m,
               "triangulate: need 0 < min_depth_m < max_depth_m, got {} and {}", min_depth_m,
               max_depth_m);
  EPILOC_CHECK(min_observations >= 2, "triangulate: min_observations must be >= 2, got {}",
               min_observations);
  EPILOC_CHECK(num_threads >= 0, "triangulate: num_threads must be >= 0, got {}", num_threads);
}

TrackTriangulation TriangulateTrack(const std::vector<TrackObservation>& observations,
                                    const Camera& camera,
                                    const TriangulateOptions& options) {
  TrackTriangulation result;
  result.inlier_mask.assign(observations.size(), 1);
  if (static_cast<int>(observations.size()) < options.min_observations) return result;

  // Solved about the first camera's centre: x_cam = R (x' + c0) + t = R x' + (R c0 + t).
  const Eigen::Vector3d origin = -(observations.front().cam_from_world.rotation.conjugate() *
                                   observations.front().cam_from_world.translation);
  std::vector<TrackObservation> local = observations;
  for (TrackObservation& o : local)
    o.cam_from_world.translation += o.cam_from_world.rotation * origin;

  const double max_squared = options.max_reprojection_error_px * options.max_reprojection_error_px;
  std::vector<char>& keep = result.inlier_mask;
  Eigen::Vector3d point;
  while (true) {
    if (static_cast<int>(std::count(keep.begin(), keep.end(), 1)) < options.min_observations) {
      return result;
    }
    if (!TriangulateDlt(local, keep, camera, point)) return result;
    RefinePoint(local, keep, camera, point);
    // Worst kept observation: behind its camera or out of the depth range counts as the worst.
    int worst = -1;
    double worst_squared = max_squared;
    for (size_t k = 0; k < local.size(); ++k) {
      if (!keep[k]) continue;
      const Residual r = ReprojectionResidual(local[k], point, camera, options);
      const double squared = r.in_range ? r.squared_px : std::numeric_limits<double>::infinity();
      if (squared > worst_squared) {
        worst_squared = squared;
        worst = static_cast<int>(k);
      }
    }
    if (worst < 0) break;
    keep[worst] = 0;
  }

  double sum_squared = 0.0;
  int num_kept = 0;
  std::vector<Eigen::Vector3d> rays;
  for (size_t k = 0; k < local.size(); ++k) {
    if (!keep[k]) continue;
    sum_squared += ReprojectionResidual(local[k], point, camera, options).squared_px;
    ++num_kept;
    const Eigen::Vector3d center =
        -(local[k].cam_from_world.rotation.conjugate() * local[k].cam_from_world.translation);
    rays.push_back((point - center).normalized());
  }
  double min_cos = 1.0;
  for (size_t a = 0; a < rays.size(); ++a) {
    for (size_t b = a + 1; b < rays.size(); ++b) min_cos = std::min(min_cos, rays[a].dot(rays[b]));
  }
  result.max_angle_deg = std::acos(std::clamp(min_cos, -1.0, 1.0)) * 180.0 / kPi;
  result.rms_error_px = std::sqrt(sum_squared / num_kept);
  result.point_in_world = point + origin;
  result.valid = result.max_angle_deg >= options.min_triangulation_angle_deg;
  return result;
}

TriangulateSummary TriangulateDatabase(Database& db,
                                       const TriangulateOptions& options,
                                       const ProgressCallback& progress) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  const int num_threads = options.num_threads > 0
                              ? options.num_threads
                              : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  TriangulateSummary summary;

  std::vector<std::pair<DbDrive, std::vector<DbFrame>>> drives;
  int64_t total_frames = 0;
  for (const DbDrive& drive : db.ReadDrives()) {
    std::vector<DbFrame> frames;
    int64_t without = 0;
    for (DbFrame& frame : db.ReadFrames(drive.drive_id)) {
      if (frame.enu_from_cam) {
        frames.push_back(std::move(frame));
      } else {
        ++without;
      }
    }
    if (without > 0) {
      spdlog::warn("{}: drive '{}': {} frames without orientation are not triangulated", db.path(),
                   drive.name, without);
    }
    summary.frames_without_orientation += without;
    if (frames.size() < 2) continue;
    total_frames += static_cast<int64_t>(frames.size());
    drives.emplace_back(drive, std::move(frames));
  }

  int64_t done = 0;
  auto frames_done = [&](int64_t n) {
    done += n;
    if (progress) progress(done, total_frames);
  };
  std::vector<PointRecord> points;
  for (const auto& [drive, frames] : drives) {
    ++summary.num_drives;
    summary.num_frames += static_cast<int64_t>(frames.size());
    TriangulateDrive(db, drive, frames, options, num_threads, frames_done, summary, points);
  }
  const auto written = std::chrono::steady_clock::now();

  {
    Database::Transaction transaction(db);
    db.ClearPoints();
    for (const PointRecord& record : points) db.WritePoint(record.point, record.observations);
    transaction.Commit();
  }
  spdlog::debug("triangulate: matching and triangulation {:.2f} s, writing {} points {:.2f} s",
                std::chrono::duration<double>(written - start).count(), points.size(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - written).count());
  double sum_error = 0.0;
  for (const PointRecord& record : points) {
    summary.num_observations += record.point.num_observations;
    sum_error += record.point.error_px;
  }
  summary.num_points = static_cast<int64_t>(points.size());
  if (!points.empty()) {
    summary.mean_track_length =
        static_cast<double>(summary.num_observations) / static_cast<double>(points.size());
    summary.mean_error_px = sum_error / static_cast<double>(points.size());
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace epiloc
