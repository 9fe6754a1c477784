#include "epiloc/synth/lighting.h"

#include <algorithm>
#include <cmath>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr double kDeg = M_PI / 180.0;
// A hit nearer than this along the ray is the receiving point's own edge (shared corners of
// neighbouring quads), not an occluder; far below a texel (>= 5 mm) of any texture.
constexpr double kMinHitM = 1e-6;

// Surfaces that cannot shade anything the cameras see: the ground and road lie below everything,
// and a ray leaving the road towards the sun meets the kerb face before the pavement's top.
bool CastsShadow(const Surface& s) {
  return s.texture >= 0 && s.kind != SurfaceKind::kGround && s.kind != SurfaceKind::kRoad &&
         s.kind != SurfaceKind::kSidewalk;
}

// Projection along the sun onto the plane z = 0: all points of one sun ray meet there.
Eigen::Vector2d Project(const Eigen::Vector3d& x, const Eigen::Vector3d& sun) {
  return x.head<2>() - (x.z() / sun.z()) * sun.head<2>();
}

Lighting::Caster MakeCaster(const Surface& s, int id, const Eigen::Vector3d& sun) {
  Lighting::Caster c;
  c.surface = id;
  c.normal = s.Normal();
  c.offset = s.PlaneOffset();
  c.origin = s.texture_origin_in_world;
  c.u = s.u_axis;
  c.v = s.v_axis;
  std::array<Eigen::Vector2d, 4> uv;
  double area = 0;
  c.lo = Eigen::Vector2d::Constant(1e300);
  c.hi = Eigen::Vector2d::Constant(-1e300);
  for (int k = 0; k < 4; ++k) {
    uv[k] = s.TextureCoordinates(s.corners_in_world[k]);
    const Eigen::Vector2d p = Project(s.corners_in_world[k], sun);
    c.lo = c.lo.cwiseMin(p);
    c.hi = c.hi.cwiseMax(p);
  }
  for (int k = 0; k < 4; ++k)
    area += uv[k].x() * uv[(k + 1) % 4].y() - uv[k].y() * uv[(k + 1) % 4].x();
  const double orient = area >= 0 ? 1.0 : -1.0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d e = (uv[(k + 1) % 4] - uv[k]).normalized() * orient;
    c.edges[k] = Eigen::Vector3d(-e.y(), e.x(), e.y() * uv[k].x() - e.x() * uv[k].y());
  }
  return c;
}

// Does the ray p + t * sun, t > kMinHitM, pass through the caster?
bool Hits(const Lighting::Caster& c, const Eigen::Vector3d& p, const Eigen::Vector3d& sun) {
  const double denom = c.normal.dot(sun);
  if (std::abs(denom) < 1e-12) return false;
  const double t = (c.offset - c.normal.dot(p)) / denom;
  if (t <= kMinHitM) return false;
  const Eigen::Vector3d q = p + t * sun - c.origin;
  const double u = q.dot(c.u), v = q.dot(c.v);
  for (const Eigen::Vector3d& e : c.edges) {
    if (e.x() * u + e.y() * v + e.z() < 0) return false;
  }
  return true;
}

// Does the convex polygon `poly` overlap the square [lo, hi]? (Separating axes: the polygon's
// edges; the square's axes are covered by the caller's bounding-box test.)
bool Overlaps(const std::array<Eigen::Vector2d, 4>& poly,
              const Eigen::Vector2d& lo,
              const Eigen::Vector2d& hi) {
  double area = 0;
  for (int k = 0; k < 4; ++k) {
    area += poly[k].x() * poly[(k + 1) % 4].y() - poly[k].y() * poly[(k + 1) % 4].x();
  }
  if (std::abs(area) < 1e-9) return true;  // seen edge-on: a segment, keep its bounding box
  const double orient = area > 0 ? 1.0 : -1.0;
  const std::array<Eigen::Vector2d, 4> square = {lo, Eigen::Vector2d(hi.x(), lo.y()), hi,
                                                 Eigen::Vector2d(lo.x(), hi.y())};
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d e = poly[(k + 1) % 4] - poly[k];
    if (e.squaredNorm() < 1e-18) continue;
    bool all_outside = true;
    for (const Eigen::Vector2d& q : square) {
      const Eigen::Vector2d d = q - poly[k];
      all_outside = all_outside && orient * (e.x() * d.y() - e.y() * d.x()) < -1e-9;
    }
    if (all_outside) return false;
  }
  return true;
}

}  // namespace

void SunOptions::Check() const {
  EPILOC_CHECK(std::isfinite(azimuth_deg), "sun options: azimuth_deg is not finite");
  EPILOC_CHECK(elevation_deg >= 10 && elevation_deg <= 90,
               "sun options: elevation_deg = {} must be in [10, 90] (lower suns cast shadows "
               "longer than the world)",
               elevation_deg);
  EPILOC_CHECK(ambient >= 0 && direct >= 0 && ambient + direct > 0 && std::isfinite(ambient) &&
                   std::isfinite(direct),
               "sun options: ambient = {} and direct = {} must not be negative", ambient, direct);
}

Eigen::Vector3d SunOptions::DirectionInWorld() const {
  const double az = azimuth_deg * kDeg, el = elevation_deg * kDeg;
  return Eigen::Vector3d(std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el));
}

Lighting::Lighting(const World& world, const SunOptions& sun)
    : sun_(sun), num_world_surfaces_(static_cast<int>(world.surfaces.size())) {
  sun_.Check();
  direction_ = sun_.DirectionInWorld();
  normals_.reserve(world.surfaces.size());
  offsets_.reserve(world.surfaces.size());
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = Eigen::Vector2d::Constant(-1e300);
  for (int i = 0; i < num_world_surfaces_; ++i) {
    const Surface& s = world.surfaces[i];
    normals_.push_back(s.Normal());
    offsets_.push_back(s.PlaneOffset());
    if (!CastsShadow(s)) continue;
    casters_.push_back(MakeCaster(s, i, direction_));
    lo = lo.cwiseMin(casters_.back().lo);
    hi = hi.cwiseMax(casters_.back().hi);
  }
  if (casters_.empty()) return;
  // 1 m cells: a cell holds a few casters (a facade band, a kerb, a car's faces), and the
  // index of a 300 m street stays at a few MB.
  cell_m_ = 1.0;
  grid_origin_ = lo;
  grid_cols_ = static_cast<int>(std::floor((hi.x() - lo.x()) / cell_m_)) + 1;
  grid_rows_ = static_cast<int>(std::floor((hi.y() - lo.y()) / cell_m_)) + 1;
  std::vector<std::vector<int>> cells(static_cast<size_t>(grid_cols_) * grid_rows_);
  for (int k = 0; k < static_cast<int>(casters_.size()); ++k) {
    const Caster& c = casters_[k];
    const Surface& s = world.surfaces[c.surface];
    std::array<Eigen::Vector2d, 4> poly;
    for (int j = 0; j < 4; ++j) poly[j] = Project(s.corners_in_world[j], direction_);
    const int i0 = static_cast<int>((c.lo.x() - lo.x()) / cell_m_);
    const int i1 = std::min(grid_cols_ - 1, static_cast<int>((c.hi.x() - lo.x()) / cell_m_));
    const int j0 = static_cast<int>((c.lo.y() - lo.y()) / cell_m_);
    const int j1 = std::min(grid_rows_ - 1, static_cast<int>((c.hi.y() - lo.y()) / cell_m_));
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const Eigen::Vector2d a = lo + cell_m_ * Eigen::Vector2d(i, j);
        if (Overlaps(poly, a, a + Eigen::Vector2d::Constant(cell_m_))) {
          cells[static_cast<size_t>(j) * grid_cols_ + i].push_back(k);
        }
      }
    }
  }
  cell_start_.resize(cells.size() + 1);
  cell_start_[0] = 0;
  for (size_t i = 0; i < cells.size(); ++i) {
    cell_start_[i + 1] = cell_start_[i] + static_cast<int>(cells[i].size());
    cell_casters_.insert(cell_casters_.end(), cells[i].begin(), cells[i].end());
  }
}

bool Lighting::Occluded(const Eigen::Vector3d& p,
                        int surface,
                        const std::vector<Caster>& extra) const {
  const Eigen::Vector2d g = Project(p, direction_);
  for (const Caster& c : extra) {
    if (c.surface == surface || g.x() < c.lo.x() || g.y() < c.lo.y() || g.x() > c.hi.x() ||
        g.y() > c.hi.y())
      continue;
    if (Hits(c, p, direction_)) return true;
  }
  const double fx = (g.x() - grid_origin_.x()) / cell_m_, fy = (g.y() - grid_origin_.y()) / cell_m_;
  if (!(fx >= 0 && fy >= 0 && fx < grid_cols_ && fy < grid_rows_)) return false;
  const size_t cell = static_cast<size_t>(fy) * grid_cols_ + static_cast<size_t>(fx);
  for (int k = cell_start_[cell]; k < cell_start_[cell + 1]; ++k) {
    const Caster& c = casters_[cell_casters_[k]];
    if (c.surface != surface && Hits(c, p, direction_)) return true;
  }
  return false;
}

bool Lighting::InShadow(const Eigen::Vector3d& point_in_world,
                        int surface,
                        const std::vector<Surface>* extra) const {
  std::vector<Caster> extra_casters;
  if (extra) {
    for (size_t k = 0; k < extra->size(); ++k) {
      if ((*extra)[k].texture >= 0) {
        extra_casters.push_back(
            MakeCaster((*extra)[k], num_world_surfaces_ + static_cast<int>(k), direction_));
      }
    }
  }
  return Occluded(point_in_world, surface, extra_casters);
}

void Lighting::Shade(const Camera& pinhole,
                     const Rigid3d& cam_from_world,
                     const std::vector<Surface>* extra,
                     const cv::Mat& ids,
                     const cv::Mat& inverse_depth,
                     cv::Mat* colour) const {
  const int num_extra = extra ? static_cast<int>(extra->size()) : 0;
  const Eigen::Matrix3d world_from_cam = cam_from_world.rotation.toRotationMatrix().transpose();
  const Eigen::Vector3d centre = -(world_from_cam * cam_from_world.translation);
  // Per surface: cos(incidence) of the side the camera sees (<= 0: that side faces away).
  std::vector<float> cos_incidence(num_world_surfaces_ + num_extra, 0.0f);
  std::vector<Caster> extra_casters;
  const auto facing_cos = [&](const Eigen::Vector3d& normal, const Eigen::Vector3d& on_plane) {
    const double side = normal.dot(centre - on_plane) >= 0 ? 1.0 : -1.0;
    return static_cast<float>(side * normal.dot(direction_));
  };
  // Only surfaces seen in this image matter; mark them first (a street has ~10^4 surfaces).
  std::vector<char> seen(cos_incidence.size(), 0);
  for (int y = 0; y < ids.rows; ++y) {
    const int* row = ids.ptr<int>(y);
    for (int x = 0; x < ids.cols; ++x) {
      if (row[x] >= 0) seen[row[x]] = 1;
    }
  }
  for (int i = 0; i < num_world_surfaces_; ++i) {
    // normal * offset lies on the plane (normal . x = offset, |normal| = 1).
    if (seen[i]) cos_incidence[i] = facing_cos(normals_[i], normals_[i] * offsets_[i]);
  }
  for (int k = 0; k < num_extra; ++k) {
    const Surface& s = (*extra)[k];
    if (s.texture < 0) continue;
    extra_casters.push_back(MakeCaster(s, num_world_surfaces_ + k, direction_));
    if (seen[num_world_surfaces_ + k]) {
      cos_incidence[num_world_surfaces_ + k] = facing_cos(s.Normal(), s.texture_origin_in_world);
    }
  }
  const float ambient = static_cast<float>(sun_.ambient), direct = static_cast<float>(sun_.direct);
  for (int y = 0; y < ids.rows; ++y) {
    const int* id_row = ids.ptr<int>(y);
    const double* w_row = inverse_depth.ptr<double>(y);
    cv::Vec3f* c_row = colour->ptr<cv::Vec3f>(y);
    const double ry = (y - pinhole.cy) / pinhole.fy;
    for (int x = 0; x < ids.cols; ++x) {
      const int id = id_row[x];
      if (id < 0) continue;
      const float cos_i = cos_incidence[id];
      float factor = ambient;
      if (cos_i > 0) {
        const Eigen::Vector3d ray((x - pinhole.cx) / pinhole.fx, ry, 1.0);
        const Eigen::Vector3d p = centre + world_from_cam * (ray / w_row[x]);
        if (!Occluded(p, id, extra_casters)) {
          factor += direct * cos_i;
        }
      }
      c_row[x] *= factor;
    }
  }
}

}  // namespace epiloc
