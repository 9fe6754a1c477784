#include "epiloc/anchor/structure_registration.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <flann/flann.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

enum class RobustLoss { kHuber, kTukey };

double RobustWeight(double residual, double scale, RobustLoss loss) {
  const double a = std::abs(residual);
  if (loss == RobustLoss::kHuber) return a <= scale ? 1.0 : scale / a;
  if (a >= scale) return 0.0;
  const double u = 1.0 - (a / scale) * (a / scale);
  return u * u;
}

// One paired point: its transformed position, the map point, the projector of the distance, and
// the derivative of the transformed position by the drift kappa (map frame).
struct Pair {
  Eigen::Vector3d y;
  Eigen::Vector3d q;
  Eigen::Matrix3d p;
  Eigen::Vector3d k;
  size_t index = 0;  // of the point
};

// The structure as registered: points, their drift directions (ScaleDriftPath; null: no
// drift) and the current drift.
struct Warped {
  const std::vector<Eigen::Vector3d>& points;
  const std::vector<Eigen::Vector3d>* directions = nullptr;
  double kappa = 0.0;

  Eigen::Vector3d Point(size_t i) const {
    return directions ? Eigen::Vector3d(points[i] + kappa * (*directions)[i]) : points[i];
  }
};

std::vector<Pair> FindPairs(const Warped& structure,
                            const Similarity3& sim,
                            StructureMap& map,
                            double max_distance_m) {
  const size_t n = structure.points.size();
  std::vector<Eigen::Vector3d> transformed(n);
  for (size_t i = 0; i < n; ++i) transformed[i] = sim * structure.Point(i);
  const std::vector<int> nearest = map.Nearest(transformed, max_distance_m);
  std::vector<Pair> pairs;
  pairs.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    if (nearest[i] < 0) continue;
    const Eigen::Vector3d k =
        structure.directions
            ? Eigen::Vector3d(sim.scale * (sim.rotation * (*structure.directions)[i]))
            : Eigen::Vector3d::Zero();
    pairs.push_back({transformed[i], map.Point(nearest[i]).cast<double>(),
                     map.Projector(nearest[i]).cast<double>(), k, i});
  }
  return pairs;
}

double PairResidual(const Pair& pair) { return (pair.p * (pair.y - pair.q)).norm(); }

using Matrix8d = Eigen::Matrix<double, 8, 8>;
using Vector8d = Eigen::Matrix<double, 8, 1>;

// Which turns of the structure a Gauss-Newton step frees: all, the heading only (turns about the
// map's vertical axis: pitch and roll held), or none.
enum class Turns { kAll, kHeadingOnly, kNone };

// Gauss-Newton normal equations in (omega, delta, sigma, kappa) about `centre`: y' = exp(sigma) *
// Exp(omega) * (y + k dkappa - centre) + centre + delta. Of omega, only the turns `turns` frees
// move; without `with_scale`, sigma is held at 0; without `with_drift`, kappa.
void Accumulate(const std::vector<Pair>& pairs,
                const Eigen::Vector3d& centre,
                double loss_scale,
                RobustLoss loss,
                Turns turns,
                bool with_scale,
                bool with_drift,
                Matrix8d* h,
                Vector8d* g) {
  h->setZero();
  g->setZero();
  for (const Pair& pair : pairs) {
    const Eigen::Vector3d d = pair.y - centre;
    const Eigen::Vector3d r = pair.p * (pair.y - pair.q);
    Eigen::Matrix<double, 3, 8> j;
    j << -Skew(d), Eigen::Matrix3d::Identity(), d, pair.k;
    const double w = RobustWeight(r.norm(), loss_scale, loss);
    // P is a symmetric projector: J^T P^T P J = J^T P J.
    *h += w * j.transpose() * pair.p * j;
    *g += w * j.transpose() * r;
  }
  const bool with_tilt = turns == Turns::kAll;
  const bool with_heading = turns != Turns::kNone;
  for (const int held : {with_tilt ? -1 : 0, with_tilt ? -1 : 1, with_heading ? -1 : 2,
                         with_scale ? -1 : 6, with_drift ? -1 : 7}) {
    if (held < 0) continue;
    h->row(held).setZero();
    h->col(held).setZero();
    (*h)(held, held) = 1.0;
    (*g)(held) = 0.0;
  }
}

Eigen::Vector3d Centroid(const std::vector<Pair>& pairs) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const Pair& p : pairs) c += p.y;
  return pairs.empty() ? c : Eigen::Vector3d(c / static_cast<double>(pairs.size()));
}

// The seed search (see the header): the best of a grid of turns about the structure's centroid
// and horizontal moves, by the truncated squared distance of a subsample to the map.
Similarity3 SearchSeed(const std::vector<Eigen::Vector3d>& points,
                       const StructureMap& map,
                       const Similarity3& seed,
                       const Eigen::Vector3d& direction,
                       const StructureRegistrationOptions& options,
                       Eigen::Vector3d* best_offset,
                       double* best_yaw_deg) {
  std::vector<Eigen::Vector3d> sample;
  const size_t step = std::max<size_t>(1, points.size() / options.search_points);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < points.size(); i += step) {
    sample.push_back(seed * points[i]);
    centre += sample.back();
  }
  centre /= static_cast<double>(sample.size());
  Eigen::Vector3d along(direction.x(), direction.y(), 0.0);
  along = along.norm() > 0 ? along.normalized() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(along);
  const int na = static_cast<int>(std::floor(options.search_along_m / options.search_step_m));
  const int nl = static_cast<int>(std::floor(options.search_lateral_m / options.search_step_m));
  const int ny = static_cast<int>(std::floor(options.search_yaw_deg / options.search_yaw_step_deg));
  int best = -1;
  int best_move = 0;
  *best_offset = Eigen::Vector3d::Zero();
  *best_yaw_deg = 0.0;
  std::vector<Eigen::Vector3d> turned(sample.size());
  for (int iy = -ny; iy <= ny; ++iy) {
    const double yaw_deg = iy * options.search_yaw_step_deg;
    const Eigen::Matrix3d r =
        Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (size_t i = 0; i < sample.size(); ++i) turned[i] = r * (sample[i] - centre) + centre;
    for (int ia = -na; ia <= na; ++ia) {
      for (int il = -nl; il <= nl; ++il) {
        const Eigen::Vector3d offset = (ia * along + il * across) * options.search_step_m;
        int hits = 0;
        for (const Eigen::Vector3d& y : turned) hits += map.Occupied(y + offset) ? 1 : 0;
        // Ties (a flat score) keep the smallest change.
        const int move = std::abs(ia) + std::abs(il) + std::abs(iy);
        if (hits > best || (hits == best && move < best_move)) {
          best = hits;
          best_move = move;
          *best_offset = offset;
          *best_yaw_deg = yaw_deg;
        }
      }
    }
  }
  // The turn about the centroid, then the move, composed onto the seed.
  const Eigen::Quaterniond turn(
      Eigen::AngleAxisd(*best_yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
  Similarity3 out = seed;
  out.rotation = (turn * seed.rotation).normalized();
  out.translation = turn * (seed.translation - centre) + centre + *best_offset;
  return out;
}

}  // namespace

ScaleDriftPath::ScaleDriftPath(std::vector<Eigen::Vector3d> centres, size_t pivot)
    : centres_(std::move(centres)) {
  EPILOC_CHECK(pivot < centres_.size(), "scale drift path: pivot {} of {} cameras", pivot,
               centres_.size());
  const size_t n = centres_.size();
  arc_.assign(n, 0.0);
  integral_.assign(n, Eigen::Vector3d::Zero());
  // Each step of the path a straight piece: its share of the integral of x t dx is its
  // displacement (from the pivot's side) times the arc length at its middle (negative behind
  // the pivot, where the displacement points backwards too).
  for (size_t k = pivot + 1; k < n; ++k) {
    const Eigen::Vector3d step = centres_[k] - centres_[k - 1];
    arc_[k] = arc_[k - 1] + step.norm();
    integral_[k] = integral_[k - 1] + 0.5 * (arc_[k - 1] + arc_[k]) * step;
  }
  for (size_t k = pivot; k-- > 0;) {
    const Eigen::Vector3d step = centres_[k] - centres_[k + 1];
    arc_[k] = arc_[k + 1] - step.norm();
    integral_[k] = integral_[k + 1] + 0.5 * (arc_[k + 1] + arc_[k]) * step;
  }
}

Eigen::Vector3d ScaleDriftPath::Direction(const Eigen::Vector3d& point, size_t reference) const {
  EPILOC_CHECK(reference < centres_.size(), "scale drift path: camera {} of {}", reference,
               centres_.size());
  return arc_[reference] * (point - centres_[reference]) + integral_[reference];
}

Eigen::Vector3d ScaleDriftPath::Camera(size_t index, double kappa) const {
  EPILOC_CHECK(index < centres_.size(), "scale drift path: camera {} of {}", index,
               centres_.size());
  return centres_[index] + kappa * integral_[index];
}

Similarity3 Similarity3::Inverse() const {
  Similarity3 inverse;
  inverse.scale = 1.0 / scale;
  inverse.rotation = rotation.conjugate();
  inverse.translation = -(inverse.scale * (inverse.rotation * translation));
  return inverse;
}

void StructureRegistrationOptions::Check() const {
  EPILOC_CHECK(!max_distances_m.empty(), "structure registration: no correspondence distance");
  for (size_t i = 0; i < max_distances_m.size(); ++i) {
    EPILOC_CHECK(std::isfinite(max_distances_m[i]) && max_distances_m[i] > 0.0,
                 "structure registration: distances must be > 0");
    EPILOC_CHECK(i == 0 || max_distances_m[i] <= max_distances_m[i - 1],
                 "structure registration: distances must go from coarse to fine");
  }
  EPILOC_CHECK(max_iterations_per_level >= 1,
               "structure registration: max_iterations_per_level must be >= 1");
  EPILOC_CHECK(converged_m >= 0.0, "structure registration: converged_m must be >= 0");
  EPILOC_CHECK(loss_scale_ratio > 0.0, "structure registration: loss_scale_ratio must be > 0");
  EPILOC_CHECK(tukey_max_distance_m >= 0.0,
               "structure registration: tukey_max_distance_m must be >= 0");
  EPILOC_CHECK(normal_neighbours >= 3, "structure registration: normal_neighbours must be >= 3");
  EPILOC_CHECK(normal_radius_m > 0.0, "structure registration: normal_radius_m must be > 0");
  EPILOC_CHECK(max_planarity > 0.0 && max_planarity <= 1.0,
               "structure registration: max_planarity must be in (0, 1]");
  EPILOC_CHECK(max_linearity > 0.0 && max_linearity <= 1.0,
               "structure registration: max_linearity must be in (0, 1]");
  EPILOC_CHECK(search_along_m >= 0.0 && search_lateral_m >= 0.0 && search_step_m >= 0.0 &&
                   search_yaw_deg >= 0.0 && search_yaw_step_deg > 0.0 && search_points >= 1 &&
                   search_truncation_m > 0.0 && search_height_m >= 0.0,
               "structure registration: invalid seed search ranges");
  EPILOC_CHECK(profile_moves >= 0, "structure registration: profile_moves must be >= 0");
  EPILOC_CHECK(min_scale_distance_m > 0.0,
               "structure registration: min_scale_distance_m must be > 0");
  EPILOC_CHECK(max_scale_drift_per_m >= 0.0,
               "structure registration: max_scale_drift_per_m must be >= 0");
  EPILOC_CHECK(min_inlier_share >= 0.0 && min_inlier_share <= 1.0,
               "structure registration: min_inlier_share must be in [0, 1]");
  EPILOC_CHECK(min_points >= 7, "structure registration: min_points must be >= 7");
}

struct StructureMap::Impl {
  std::vector<Eigen::Vector3f> points;
  std::vector<float> data;  // x y z per point, for FLANN
  std::unique_ptr<flann::Index<flann::L2_Simple<float>>> index;
  std::vector<Eigen::Matrix3f> projectors;
  std::vector<uint8_t> has_projector;
  int neighbours = 12;
  double radius_m = 0.6;
  double max_planarity = 0.25;
  double max_linearity = 0.5;
  double cell_m = 0.25;                   // of the occupancy grid
  std::unordered_set<uint64_t> occupied;  // cells holding map points

  uint64_t Cell(const Eigen::Vector3d& x) const {
    const auto index = [&](double v) {
      return static_cast<uint64_t>(static_cast<int64_t>(std::floor(v / cell_m)) & 0x1FFFFF);
    };
    return index(x.x()) | index(x.y()) << 21 | index(x.z()) << 42;
  }
};

StructureMap::StructureMap(const PointCloud& cloud, const StructureRegistrationOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.Check();
  impl_->points = cloud.positions;
  impl_->neighbours = options.normal_neighbours;
  impl_->radius_m = options.normal_radius_m;
  impl_->max_planarity = options.max_planarity;
  impl_->max_linearity = options.max_linearity;
  impl_->cell_m = 0.5 * options.search_truncation_m;
  const int layers = static_cast<int>(std::ceil(options.search_height_m / impl_->cell_m - 1e-9));
  impl_->occupied.reserve(impl_->points.size() * static_cast<size_t>(2 * layers + 1));
  for (const Eigen::Vector3f& p : impl_->points) {
    for (int dz = -layers; dz <= layers; ++dz) {
      impl_->occupied.insert(
          impl_->Cell(p.cast<double>() + Eigen::Vector3d(0.0, 0.0, dz * impl_->cell_m)));
    }
  }
  impl_->projectors.assign(impl_->points.size(), Eigen::Matrix3f::Identity());
  impl_->has_projector.assign(impl_->points.size(), 0);
  if (impl_->points.empty()) return;
  impl_->data.resize(3 * impl_->points.size());
  for (size_t i = 0; i < impl_->points.size(); ++i) {
    for (int k = 0; k < 3; ++k) impl_->data[3 * i + k] = impl_->points[i][k];
  }
  flann::Matrix<float> matrix(impl_->data.data(), impl_->points.size(), 3);
  impl_->index = std::make_unique<flann::Index<flann::L2_Simple<float>>>(
      matrix, flann::KDTreeSingleIndexParams(12));
  impl_->index->buildIndex();
}

StructureMap::~StructureMap() = default;

size_t StructureMap::size() const { return impl_->points.size(); }

const Eigen::Vector3f& StructureMap::Point(int index) const {
  return impl_->points[static_cast<size_t>(index)];
}

int StructureMap::Nearest(const Eigen::Vector3d& x, double max_distance_m) const {
  return Nearest(std::vector<Eigen::Vector3d>{x}, max_distance_m).front();
}

std::vector<int> StructureMap::Nearest(const std::vector<Eigen::Vector3d>& x,
                                       double max_distance_m) const {
  std::vector<int> out(x.size(), -1);
  if (!impl_->index || x.empty()) return out;
  std::vector<float> queries(3 * x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    for (int k = 0; k < 3; ++k) queries[3 * i + k] = static_cast<float>(x[i][k]);
  }
  std::vector<size_t> indices(x.size());
  std::vector<float> distances(x.size());
  flann::Matrix<float> q(queries.data(), x.size(), 3);
  flann::Matrix<size_t> im(indices.data(), x.size(), 1);
  flann::Matrix<float> dm(distances.data(), x.size(), 1);
  // The nearest within the distance: a search bounded by it from the start (L2_Simple: squared
  // distances), which skips the kd-tree's cells beyond it.
  flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED);
  params.cores = 1;
  params.max_neighbors = 1;
  params.sorted = false;
  impl_->index->radiusSearch(q, im, dm, static_cast<float>(max_distance_m * max_distance_m),
                             params);
  for (size_t i = 0; i < x.size(); ++i) {
    if (indices[i] != static_cast<size_t>(-1)) out[i] = static_cast<int>(indices[i]);
  }
  return out;
}

bool StructureMap::Occupied(const Eigen::Vector3d& x) const {
  return impl_->occupied.count(impl_->Cell(x)) > 0;
}

const Eigen::Matrix3f& StructureMap::Projector(int index) {
  const size_t k = static_cast<size_t>(index);
  Eigen::Matrix3f& projector = impl_->projectors[k];
  if (impl_->has_projector[k]) return projector;
  impl_->has_projector[k] = 1;
  const int n = std::min<int>(impl_->neighbours, static_cast<int>(impl_->points.size()));
  std::vector<size_t> indices(static_cast<size_t>(n));
  std::vector<float> distances(static_cast<size_t>(n));
  float query[3] = {impl_->points[k].x(), impl_->points[k].y(), impl_->points[k].z()};
  flann::Matrix<float> q(query, 1, 3);
  flann::Matrix<size_t> im(indices.data(), 1, static_cast<size_t>(n));
  flann::Matrix<float> dm(distances.data(), 1, static_cast<size_t>(n));
  flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED);
  params.cores = 1;
  const int found = impl_->index->knnSearch(q, im, dm, n, params);
  const float radius2 = static_cast<float>(impl_->radius_m * impl_->radius_m);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  int used = 0;
  for (int j = 0; j < found; ++j) {
    if (distances[j] > radius2) continue;
    mean += impl_->points[indices[j]].cast<double>();
    ++used;
  }
  if (used < 5) return projector;  // a point
  mean /= used;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int j = 0; j < found; ++j) {
    if (distances[j] > radius2) continue;
    const Eigen::Vector3d d = impl_->points[indices[j]].cast<double>() - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
  const Eigen::Vector3d values = solver.eigenvalues();  // ascending
  if (values[1] > 0.0 && values[0] <= impl_->max_planarity * values[1]) {
    const Eigen::Vector3f n = solver.eigenvectors().col(0).normalized().cast<float>();
    projector = n * n.transpose();
  } else if (values[2] > 0.0 && values[1] <= impl_->max_linearity * values[2]) {
    const Eigen::Vector3f a = solver.eigenvectors().col(2).normalized().cast<float>();
    projector = Eigen::Matrix3f::Identity() - a * a.transpose();
  }
  return projector;
}

StructureRegistration RegisterStructure(const std::vector<Eigen::Vector3d>& points,
                                        StructureMap& map,
                                        const Similarity3& initial,
                                        const Eigen::Vector3d& direction,
                                        const StructureRegistrationOptions& options,
                                        const StructureDrift* drift) {
  options.Check();
  StructureRegistration result;
  result.map_from_world = initial;
  result.num_points = static_cast<int>(points.size());
  for (const Eigen::Vector3d& p : points) {
    EPILOC_CHECK(p.allFinite(), "structure registration: a point is not finite");
  }
  if (result.num_points < options.min_points) {
    result.message = fmt::format("{} structure points, need {}", points.size(), options.min_points);
    return result;
  }
  if (drift) {
    EPILOC_CHECK(drift->directions.size() == points.size(),
                 "structure registration: {} drift directions for {} points",
                 drift->directions.size(), points.size());
    EPILOC_CHECK(std::isfinite(drift->per_m), "structure registration: the drift is not finite");
  }
  const bool with_drift = drift && drift->estimate && options.max_scale_drift_per_m > 0.0;
  // kappa is per world unit: per metre times metres per unit.
  Warped structure{points, drift ? &drift->directions : nullptr,
                   drift ? drift->per_m * initial.scale : 0.0};
  Similarity3 sim = initial;
  if (options.search_step_m > 0.0) {
    sim = SearchSeed(points, map, initial, direction, options, &result.search_offset_m,
                     &result.search_yaw_deg);
  }

  for (const double max_distance : options.max_distances_m) {
    const double loss_scale = options.loss_scale_ratio * max_distance;
    for (int it = 0; it < options.max_iterations_per_level; ++it) {
      const std::vector<Pair> pairs = FindPairs(structure, sim, map, max_distance);
      if (static_cast<int>(pairs.size()) < options.min_points) {
        result.message =
            fmt::format("{} points within {} m of the map", pairs.size(), max_distance);
        return result;
      }
      const Eigen::Vector3d centre = Centroid(pairs);
      Matrix8d h;
      Vector8d g;
      const RobustLoss loss =
          max_distance <= options.tukey_max_distance_m ? RobustLoss::kTukey : RobustLoss::kHuber;
      const bool free_scale = max_distance <= options.min_scale_distance_m;
      const bool free_tilt =
          !options.hold_tilt_coarse || max_distance <= options.tukey_max_distance_m;
      const Turns turns = options.hold_rotation ? Turns::kNone
                          : free_tilt           ? Turns::kAll
                                                : Turns::kHeadingOnly;
      Accumulate(pairs, centre, loss_scale, loss, turns, free_scale, free_scale && with_drift, &h,
                 &g);
      // A little damping keeps directions the structure does not constrain where they are.
      h.diagonal() += 1e-6 * (h.diagonal().maxCoeff() + 1.0) * Vector8d::Ones();
      const Vector8d step = h.ldlt().solve(-g);
      if (!step.allFinite()) {
        result.message = "singular registration problem";
        return result;
      }
      const Eigen::Vector3d omega = step.head<3>();
      const Eigen::Vector3d delta = step.segment<3>(3);
      const double sigma = step[6];
      double radius = 0.0;
      for (const Pair& p : pairs) radius = std::max(radius, (p.y - centre).norm());
      const double angle = omega.norm();
      const Eigen::Quaterniond dr =
          angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle))
                      : Eigen::Quaterniond::Identity();
      const double ds = std::exp(sigma);
      sim.scale *= ds;
      sim.rotation = (dr * sim.rotation).normalized();
      sim.translation = ds * (dr * (sim.translation - centre)) + centre + delta;
      // The drift within its bound (per metre of road: kappa per world unit over the scale).
      const double old_kappa = structure.kappa;
      const double max_kappa = options.max_scale_drift_per_m * sim.scale;
      structure.kappa = std::clamp(structure.kappa + step[7], -max_kappa, max_kappa);
      double moved_by_drift = 0.0;
      for (const Pair& p : pairs) {
        moved_by_drift =
            std::max(moved_by_drift, std::abs(structure.kappa - old_kappa) * p.k.norm());
      }
      ++result.iterations;
      if (delta.norm() + (angle + std::abs(sigma)) * radius + moved_by_drift <
          options.converged_m) {
        break;
      }
    }
  }
  result.map_from_world = sim;
  result.drift = structure.kappa;
  result.scale_drift_per_m = structure.kappa / sim.scale;
  const double finest = options.max_distances_m.back();
  const std::vector<Pair> pairs = FindPairs(structure, sim, map, finest);
  result.num_inliers = static_cast<int>(pairs.size());
  result.inlier_share = static_cast<double>(pairs.size()) / points.size();
  if (result.num_inliers < options.min_points) {
    result.message = fmt::format("{} inliers, need {}", result.num_inliers, options.min_points);
    return result;
  }
  double sum2 = 0.0;
  for (const Pair& p : pairs) sum2 += PairResidual(p) * PairResidual(p);
  result.rms_m = std::sqrt(sum2 / pairs.size());
  // Conditioning: the unweighted Hessian of the final pairs.
  Matrix8d h;
  Vector8d g;
  Accumulate(pairs, Centroid(pairs), 1e30, RobustLoss::kHuber, Turns::kAll, true, with_drift, &h,
             &g);
  const Eigen::Vector3d u = direction.normalized();
  const Eigen::Matrix3d htt = h.block<3, 3>(3, 3);
  result.along_information = u.dot(htt * u) / pairs.size();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(htt);
  result.condition =
      eigen.eigenvalues()[0] > 0.0 ? eigen.eigenvalues()[2] / eigen.eigenvalues()[0] : INFINITY;
  const Matrix8d covariance =
      h.fullPivLu().inverse() * std::max(result.rms_m * result.rms_m, 1e-12);
  result.along_sigma_m = std::sqrt(std::max(0.0, u.dot(covariance.block<3, 3>(3, 3) * u)));
  // The Hessian sees only the final pairs: moved along the road, a structure of facades finds
  // other pairs as good (the cost is flat there, or has minima a window apart). So the fit is
  // moved along u, re-paired at each move, and which points lie on the map's surface (within the
  // finest level's loss scale) compared with the fit's: a move is not told apart from the fit
  // unless the points it takes off the surface outnumber those it puts on by twice the
  // deviation of that difference (McNemar's test on the paired outcomes: lost - gained <
  // 2 sqrt(lost + gained)), or their graded costs rise by twice their deviation (below); the
  // largest such move is taken as 2 sigma. Points that stay on a
  // facade either way carry no information about the move and no noise into the test (a test
  // of the whole count against its Poisson deviation, 2 sqrt(count), drowned the few points on
  // surfaces facing along the road in them). A move by the finest distance takes a point off
  // its pair's inlier band: finer steps add nothing.
  const double surface_m = options.loss_scale_ratio * finest;
  // Per point, with the fit moved along u: whether it lies on the map's surface (within the loss
  // scale) and its truncated squared distance to it in units of that scale (1: off it, or
  // unpaired).
  struct Surface {
    std::vector<uint8_t> on;
    std::vector<double> cost;
  };
  const auto surface_at = [&](double move_m) {
    Similarity3 moved = sim;
    moved.translation += move_m * u;
    Surface out{std::vector<uint8_t>(points.size(), 0), std::vector<double>(points.size(), 1.0)};
    for (const Pair& p : FindPairs(structure, moved, map, finest)) {
      const double r = PairResidual(p);
      out.on[p.index] = r <= surface_m ? 1 : 0;
      out.cost[p.index] = std::min((r / surface_m) * (r / surface_m), 1.0);
    }
    return out;
  };
  // The search's reach also when the search is off (a registration from a given start, e.g. a
  // neighbour's fit, is no better fixed along the road than one that searched).
  const double reach_m =
      options.search_along_m > 0.0 ? options.search_along_m : options.max_distances_m.front();
  const Surface at_fit = surface_at(0.0);
  result.along_points_on_surface =
      static_cast<int>(std::count(at_fit.on.begin(), at_fit.on.end(), uint8_t{1}));
  double better_move_m = 0.0;
  double better_margin = 0.0;
  for (int k = 1; k * finest <= reach_m + 1e-9; ++k) {
    for (const int sign : {-1, 1}) {
      const Surface at_move = surface_at(sign * k * finest);
      // Two paired tests of the move against the fit: the points it takes off the surface
      // against those it puts on (McNemar), and the changes of the points' graded costs summed
      // against twice their deviation (McNemar's test is its case of costs 0 and 1; the grades
      // count a point that moves within the band, which a sparse map's few points facing along
      // the road mostly do). The move is told apart from the fit when either test does.
      double sum = 0.0, sum2 = 0.0;
      int lost = 0, gained = 0;
      for (size_t i = 0; i < points.size(); ++i) {
        const double d = at_move.cost[i] - at_fit.cost[i];
        sum += d;
        sum2 += d * d;
        lost += at_fit.on[i] && !at_move.on[i] ? 1 : 0;
        gained += !at_fit.on[i] && at_move.on[i] ? 1 : 0;
      }
      const double deviation = std::sqrt(static_cast<double>(std::max(lost + gained, 1)));
      const bool counts_tied = lost - gained < 2.0 * deviation;
      const bool costs_tied = sum < 2.0 * std::sqrt(std::max(sum2, 1.0));
      if (counts_tied && costs_tied) result.along_ambiguity_m = k * finest;
      // A move that puts significantly more points on the surface than it takes off (McNemar).
      const double margin = (gained - lost) / deviation;
      if (margin > 2.0 && margin > better_margin) {
        better_margin = margin;
        better_move_m = sign * k * finest;
      }
    }
  }
  result.along_sigma_m = std::max(result.along_sigma_m, 0.5 * result.along_ambiguity_m);
  if (better_move_m != 0.0 && options.profile_moves > 0) {
    // The fit is not where its own structure is best placed along the road: registered again
    // from there with the levels that free the scale, no search, and kept if it ends with more
    // inliers.
    StructureRegistrationOptions again = options;
    again.search_step_m = 0.0;
    again.profile_moves = options.profile_moves - 1;
    again.max_distances_m.clear();
    for (const double d : options.max_distances_m) {
      if (d <= options.min_scale_distance_m) again.max_distances_m.push_back(d);
    }
    if (again.max_distances_m.empty()) again.max_distances_m.push_back(finest);
    Similarity3 start = sim;
    start.translation += better_move_m * u;
    StructureDrift moved_drift;
    if (drift) {
      moved_drift = *drift;
      moved_drift.per_m = result.scale_drift_per_m;
    }
    StructureRegistration moved =
        RegisterStructure(points, map, start, direction, again, drift ? &moved_drift : nullptr);
    if (moved.success && moved.num_inliers > result.num_inliers &&
        moved.inlier_share >= options.min_inlier_share) {
      moved.iterations += result.iterations;
      moved.search_offset_m = result.search_offset_m;
      moved.search_yaw_deg = result.search_yaw_deg;
      return moved;
    }
  }
  if (result.inlier_share < options.min_inlier_share) {
    result.message = fmt::format("inlier share {:.2f} below {:.2f}", result.inlier_share,
                                 options.min_inlier_share);
    return result;
  }
  result.success = true;
  return result;
}

}  // namespace epiloc
