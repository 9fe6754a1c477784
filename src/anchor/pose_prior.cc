#include "epiloc/anchor/pose_prior.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Value and derivative at 0 of the least-squares quadratic a + b t + c t^2 through (t_i, y_i).
// Returns false for a singular system.
bool FitQuadraticSlope(const std::vector<double>& t, const std::vector<double>& y, double* slope) {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d aty = Eigen::Vector3d::Zero();
  const bool quadratic = t.size() >= 4;  // 3 points: a straight line is safer
  for (size_t i = 0; i < t.size(); ++i) {
    const Eigen::Vector3d a(1.0, t[i], quadratic ? t[i] * t[i] : 0.0);
    ata += a * a.transpose();
    aty += a * y[i];
  }
  if (!quadratic) ata(2, 2) = 1.0;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
  const Eigen::Vector3d x = ldlt.solve(aty);
  if (!x.allFinite()) return false;
  *slope = x(1);
  return true;
}

}  // namespace

void PriorOptions::Check() const {
  EPILOC_CHECK(std::isfinite(camera_height_m), "--camera-height must be finite");
  EPILOC_CHECK(std::isfinite(ground_radius_m) && ground_radius_m > 0,
               "prior options: ground_radius_m must be > 0, got {}", ground_radius_m);
  EPILOC_CHECK(ground_percentile >= 0 && ground_percentile <= 100,
               "prior options: ground_percentile must be in [0, 100], got {}", ground_percentile);
  EPILOC_CHECK(min_ground_points >= 1, "prior options: min_ground_points must be >= 1");
  EPILOC_CHECK(std::isfinite(heading_window_s) && heading_window_s > 0,
               "prior options: heading_window_s must be > 0, got {}", heading_window_s);
  EPILOC_CHECK(std::isfinite(max_heading_window_s) && max_heading_window_s >= heading_window_s,
               "prior options: max_heading_window_s must be >= heading_window_s");
  EPILOC_CHECK(std::isfinite(min_heading_baseline_m) && min_heading_baseline_m >= 0,
               "prior options: min_heading_baseline_m must be >= 0");
}

void CandidateOptions::Check() const {
  EPILOC_CHECK(num_candidates >= 1, "--candidates must be >= 1, got {}", num_candidates);
  for (const double range : {yaw_range_deg, pitch_range_deg, roll_range_deg, along_range_m,
                             lateral_range_m, height_range_m}) {
    EPILOC_CHECK(std::isfinite(range) && range >= 0,
                 "candidate options: perturbation ranges must be >= 0, got {}", range);
  }
}

Eigen::Matrix3d MapFromCamRotation(double heading_deg, double pitch_deg, double roll_deg) {
  const double h = heading_deg * kDegToRad;
  const Eigen::Vector3d forward(std::sin(h), std::cos(h), 0.0);
  const Eigen::Vector3d right(std::cos(h), -std::sin(h), 0.0);
  const Eigen::Vector3d down(0.0, 0.0, -1.0);
  Eigen::Matrix3d level;
  level.col(0) = right;
  level.col(1) = down;
  level.col(2) = forward;
  // Pitch up = rotation about the camera's x axis (z turns towards -y, up); roll about z.
  const Eigen::Matrix3d pitch =
      Eigen::AngleAxisd(pitch_deg * kDegToRad, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d roll =
      Eigen::AngleAxisd(roll_deg * kDegToRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return level * pitch * roll;
}

double CameraHeadingDeg(const Eigen::Matrix3d& map_from_cam) {
  const Eigen::Vector3d forward = map_from_cam.col(2);
  double heading = std::atan2(forward.x(), forward.y()) / kDegToRad;
  if (heading < 0) heading += 360.0;
  return heading;
}

std::optional<double> TrackHeadingDeg(const PositionTrack& gnss,
                                      const EnuFrame& map_frame,
                                      double timestamp_s,
                                      const PriorOptions& options) {
  const auto& samples = gnss.samples;
  for (double window = options.heading_window_s;; window = std::min(
                                                      2.0 * window, options.max_heading_window_s)) {
    std::vector<double> t, east, north;
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(INFINITY);
    Eigen::Vector2d hi = Eigen::Vector2d::Constant(-INFINITY);
    const auto first = std::lower_bound(
        samples.begin(), samples.end(), timestamp_s - window,
        [](const PositionSample& s, double value) { return s.timestamp_s < value; });
    for (auto it = first; it != samples.end() && it->timestamp_s <= timestamp_s + window; ++it) {
      const Eigen::Vector3d p = map_frame.ToEnu(it->position);
      t.push_back(it->timestamp_s - timestamp_s);
      east.push_back(p.x());
      north.push_back(p.y());
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
    const bool enough = t.size() >= 3 && (hi - lo).norm() >= options.min_heading_baseline_m;
    if (enough) {
      double ve = 0, vn = 0;
      if (FitQuadraticSlope(t, east, &ve) && FitQuadraticSlope(t, north, &vn) &&
          std::hypot(ve, vn) > 1e-6) {
        return CompassHeadingFromEnuDirection(Eigen::Vector2d(ve, vn));
      }
    }
    if (window >= options.max_heading_window_s) return std::nullopt;
  }
}

std::optional<double> GroundHeight(const PointCloud& cloud,
                                   const Eigen::Vector2d& xy,
                                   const PriorOptions& options) {
  const float r2 = static_cast<float>(options.ground_radius_m * options.ground_radius_m);
  const Eigen::Vector2f centre = xy.cast<float>();
  std::vector<float> heights;
  for (const Eigen::Vector3f& p : cloud.positions) {
    if ((p.head<2>() - centre).squaredNorm() <= r2) heights.push_back(p.z());
  }
  if (static_cast<int>(heights.size()) < options.min_ground_points) return std::nullopt;
  const size_t k = std::min(heights.size() - 1,
                            static_cast<size_t>(options.ground_percentile / 100.0 * heights.size()));
  std::nth_element(heights.begin(), heights.begin() + k, heights.end());
  return static_cast<double>(heights[k]);
}

std::optional<PosePrior> MakePosePrior(const PositionTrack& gnss,
                                       const EnuFrame& map_frame,
                                       const PointCloud& cloud,
                                       frame_t frame,
                                       double timestamp_s,
                                       double max_gap_s,
                                       const PriorOptions& options) {
  const auto sample = gnss.Interpolate(timestamp_s, max_gap_s);
  if (!sample) return std::nullopt;
  const auto heading = TrackHeadingDeg(gnss, map_frame, timestamp_s, options);
  if (!heading) return std::nullopt;
  PosePrior prior;
  prior.frame = frame;
  prior.timestamp_s = timestamp_s;
  prior.heading_deg = *heading;
  prior.position_in_map = map_frame.ToEnu(sample->position);
  if (const auto ground = GroundHeight(cloud, prior.position_in_map.head<2>(), options)) {
    prior.has_ground = true;
    prior.ground_z_m = *ground;
    prior.position_in_map.z() = *ground + options.camera_height_m;
  }
  prior.map_from_cam = Rigid3d::FromMatrix(MapFromCamRotation(prior.heading_deg),
                                           prior.position_in_map);
  return prior;
}

std::vector<Rigid3d> GenerateCandidates(const PosePrior& prior,
                                        const CandidateOptions& options,
                                        uint64_t seed) {
  options.Check();
  struct Offset {
    double yaw_deg = 0, pitch_deg = 0, roll_deg = 0, along_m = 0, lateral_m = 0, height_m = 0;
  };
  std::vector<Offset> offsets(1);  // the prior
  const auto stencil = [&](double Offset::*field, double range) {
    if (range <= 0) return;
    for (const double sign : {1.0, -1.0}) {
      Offset o;
      o.*field = sign * range;
      offsets.push_back(o);
    }
  };
  stencil(&Offset::yaw_deg, options.yaw_range_deg);
  stencil(&Offset::along_m, options.along_range_m);
  stencil(&Offset::lateral_m, options.lateral_range_m);
  offsets.resize(std::min<size_t>(offsets.size(), options.num_candidates));
  std::mt19937_64 rng(seed);
  const auto uniform = [&](double range) {
    return std::uniform_real_distribution<double>(-range, range)(rng);
  };
  while (static_cast<int>(offsets.size()) < options.num_candidates) {
    Offset o;
    o.yaw_deg = uniform(options.yaw_range_deg);
    o.pitch_deg = uniform(options.pitch_range_deg);
    o.roll_deg = uniform(options.roll_range_deg);
    o.along_m = uniform(options.along_range_m);
    o.lateral_m = uniform(options.lateral_range_m);
    o.height_m = uniform(options.height_range_m);
    offsets.push_back(o);
  }
  const double h = prior.heading_deg * kDegToRad;
  const Eigen::Vector3d forward(std::sin(h), std::cos(h), 0.0);
  const Eigen::Vector3d right(std::cos(h), -std::sin(h), 0.0);
  std::vector<Rigid3d> poses;
  for (const Offset& o : offsets) {
    const Eigen::Vector3d centre = prior.position_in_map + o.along_m * forward +
                                   o.lateral_m * right + o.height_m * Eigen::Vector3d::UnitZ();
    poses.push_back(Rigid3d::FromMatrix(
        MapFromCamRotation(prior.heading_deg + o.yaw_deg, o.pitch_deg, o.roll_deg), centre));
  }
  return poses;
}

}  // namespace epiloc
