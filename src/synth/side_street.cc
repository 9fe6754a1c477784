#include "epiloc/synth/side_street.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"
#include "epiloc/synth/drive_line.h"
#include "epiloc/synth/world.h"

namespace epiloc {
namespace {

// The junction leaves room for a right turn of up to this radius (of the car's path; urban
// junctions are turned at 5-12 m) on a line up to 1 m right of the right lane's centre.
constexpr double kRoomTurnRadiusM = 12.0;
constexpr double kRoomLineRightM = 1.0;
// Building fronts stand this far (plus a setback) behind the kerb, as along the street.
constexpr double kFacadeFrontM = 3.0;
constexpr double kMaxSetbackM = 2.0;
constexpr double kMaxDepthM = 10.0;
// No parked car within 5 m of the kerb corners (German StVO section 12 (3) 1).
constexpr double kNoParkingM = 5.0;
// Anything standing within 1 m of the side street's pavement is removed (a sign's board reaches
// 0.45 m from its pole).
constexpr double kClearanceM = 1.0;
// The street's buildings reach at most 3 + 2.5 m (setback) + 14 m (depth) behind its pavement's
// inner edge (world.cc); the side street's own buildings start beyond them.
constexpr double kStreetBuildingsReachM = 3.0 + 2.5 + 14.0 + 2.0;

Eigen::Vector3d Lift(const Eigen::Vector2d& p, double z) { return {p.x(), p.y(), z}; }

std::vector<Eigen::Vector2d> Footprint(const Surface& s) {
  std::vector<Eigen::Vector2d> out;
  for (const Eigen::Vector3d& c : s.corners_in_world) out.push_back(c.head<2>());
  return out;
}

// Separating-axis test of two convex polygons, degenerate ones (the footprint of an upright
// quad is a segment) included: false if some axis (edge normals and directions of both) separates
// them by more than margin_m.
bool Overlap(const std::vector<Eigen::Vector2d>& a,
             const std::vector<Eigen::Vector2d>& b,
             double margin_m) {
  std::vector<Eigen::Vector2d> axes;
  for (const auto* poly : {&a, &b}) {
    for (size_t i = 0; i < poly->size(); ++i) {
      const Eigen::Vector2d e = (*poly)[(i + 1) % poly->size()] - (*poly)[i];
      if (e.norm() < 1e-9) continue;
      axes.push_back(e.normalized());
      axes.emplace_back(-e.y() / e.norm(), e.x() / e.norm());
    }
  }
  for (const Eigen::Vector2d& axis : axes) {
    double lo_a = 1e300, hi_a = -1e300, lo_b = 1e300, hi_b = -1e300;
    for (const Eigen::Vector2d& p : a) {
      lo_a = std::min(lo_a, p.dot(axis));
      hi_a = std::max(hi_a, p.dot(axis));
    }
    for (const Eigen::Vector2d& p : b) {
      lo_b = std::min(lo_b, p.dot(axis));
      hi_b = std::max(hi_b, p.dot(axis));
    }
    if (lo_b - hi_a > margin_m || lo_a - hi_b > margin_m) return false;
  }
  return true;
}

// The junction frame (see the header) and the side street's coordinates: r along its axis away
// from the street, w to the left of that direction.
struct JunctionFrame {
  Eigen::Vector2d origin, x, y, a, b;
  double phi = 0.0;

  JunctionFrame(const Centreline& street, double junction_s_m, double angle_deg)
      : origin(street.PointAt(junction_s_m)),
        x(street.TangentAt(junction_s_m)),
        y(street.LeftAt(junction_s_m)),
        phi(angle_deg * kDegToRad) {
    a = -(std::cos(phi) * x + std::sin(phi) * y);
    b = Eigen::Vector2d(-a.y(), a.x());
  }
  Eigen::Vector2d Street(double px, double py) const { return origin + px * x + py * y; }
  Eigen::Vector2d Side(double r, double w) const { return origin + r * a + w * b; }
  // Where the line y = py (parallel to the street) crosses the side street's line w.
  double XAt(double py, double w) const { return py / std::tan(phi) + w / std::sin(phi); }
  double RAt(double py, double w) const { return (-py - w * std::cos(phi)) / std::sin(phi); }
  double XOf(const Eigen::Vector2d& p) const { return (p - origin).dot(x); }
  double YOf(const Eigen::Vector2d& p) const { return (p - origin).dot(y); }
};

// Adds surfaces and their textures to a built world.
class SideStreetBuilder {
 public:
  explicit SideStreetBuilder(World* world)
      : world_(*world),
        options_(world->options.side_street),
        rng_(MixSeed(world->options.seed, 9001)),
        half_(world->options.road.asphalt_half_width_m()),
        outer_(half_ + world->options.road.sidewalk_width_m) {}

  void Build();

 private:
  // Extent of the street around the junction (x in the junction frame) that must be straight.
  void StraightExtent(double* lo, double* hi) const;
  double FindJunction() const;
  void RemoveWhatStandsInTheWay(const JunctionFrame& f, double* x_a, double* x_b);
  void AddCornerWalls(const JunctionFrame& f);
  void AddPavementAndKerbs(const JunctionFrame& f, double x_a, double x_b);
  void AddBuildings(const JunctionFrame& f, double r_begin, double r_end);

  int AddTexture(Texture texture) {
    texture.BuildPyramid();
    world_.textures.push_back(std::move(texture));
    return static_cast<int>(world_.textures.size()) - 1;
  }
  int AddSurface(SurfaceKind kind,
                 const std::array<Eigen::Vector3d, 4>& corners,
                 int texture,
                 const Eigen::Vector3d& origin,
                 const Eigen::Vector3d& u,
                 const Eigen::Vector3d& v) {
    Surface s;
    s.kind = kind;
    s.corners_in_world = corners;
    s.texture = texture;
    s.texture_origin_in_world = origin;
    s.u_axis = u;
    s.v_axis = v;
    world_.surfaces.push_back(s);
    return static_cast<int>(world_.surfaces.size()) - 1;
  }
  // A vertical rectangle seen from the side `outward` points to (as world.cc's AddUpright).
  int AddUpright(SurfaceKind kind,
                 const Eigen::Vector2d& centre,
                 const Eigen::Vector2d& outward,
                 double width,
                 double z0,
                 double z1,
                 int texture) {
    const Eigen::Vector3d right = Lift(-outward, 0).cross(Eigen::Vector3d::UnitZ()).normalized();
    const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d origin = Lift(centre, z1) - 0.5 * width * right;
    const double h = z1 - z0;
    return AddSurface(
        kind,
        {origin, origin + width * right, origin + width * right + h * down, origin + h * down},
        texture, origin, right, down);
  }
  // A horizontal convex quad at height z with a texture made for its bounding box in the axes
  // (u, left of u).
  void AddFlat(SurfaceKind kind,
               const std::array<Eigen::Vector2d, 4>& c,
               double z,
               double pixels_per_m,
               const Eigen::Vector2d& u,
               const std::function<Texture(cv::Size, double, const GroundPatch&)>& make,
               int piece) {
    const Eigen::Vector2d l(-u.y(), u.x());
    Eigen::Vector2d lo(1e18, 1e18), hi(-1e18, -1e18);
    for (const Eigen::Vector2d& p : c) {
      const Eigen::Vector2d uv(p.dot(u), p.dot(l));
      lo = lo.cwiseMin(uv);
      hi = hi.cwiseMax(uv);
    }
    const GroundPatch patch{lo.x() * u + lo.y() * l, u, l, piece};
    const cv::Size size(static_cast<int>(std::ceil((hi.x() - lo.x()) * pixels_per_m)) + 1,
                        static_cast<int>(std::ceil((hi.y() - lo.y()) * pixels_per_m)) + 1);
    const int tex = AddTexture(make(size, 1.0 / pixels_per_m, patch));
    AddSurface(kind, {Lift(c[0], z), Lift(c[1], z), Lift(c[2], z), Lift(c[3], z)}, tex,
               Lift(patch.origin_in_world, z), Lift(u, 0), Lift(l, 0));
  }
  void AddKerb(const Eigen::Vector2d& from, const Eigen::Vector2d& to, const Eigen::Vector2d& out) {
    const double width = (to - from).norm();
    if (width < 1e-3) return;
    const int tex = AddTexture(KerbTexture(width, world_.options.road.kerb_height_m, 100.0,
                                           MixSeed(world_.options.seed, 9100 + ++kerbs_)));
    AddUpright(SurfaceKind::kKerb, 0.5 * (from + to), out, width, 0.0,
               world_.options.road.kerb_height_m, tex);
  }

  World& world_;
  const SideStreetOptions& options_;
  Rng rng_;
  double half_ = 0.0, outer_ = 0.0;
  int kerbs_ = 0;
  SideStreet side_;
};

void SideStreetBuilder::StraightExtent(double* lo, double* hi) const {
  const double phi = options_.angle_deg * kDegToRad;
  // The mouth across the street's pavement: x of the lines w = +-outer between the pavement's
  // outer edge and the kerb line.
  *lo = 1e300;
  *hi = -1e300;
  for (const double y : {-outer_, -half_}) {
    *lo = std::min(*lo, y / std::tan(phi) - outer_ / std::sin(phi));
    *hi = std::max(*hi, y / std::tan(phi) + outer_ / std::sin(phi));
  }
  const double line = -0.5 * world_.options.road.lane_width_m - kRoomLineRightM;
  *hi = std::max(*hi, TurnInJoinDistance(options_.angle_deg, line, kRoomTurnRadiusM));
  *lo -= 1.0;
  *hi += 1.0;
}

double SideStreetBuilder::FindJunction() const {
  const WorldOptions& o = world_.options;
  double lo = 0, hi = 0;
  StraightExtent(&lo, &hi);
  // Candidates every metre on straights, nearest to the wanted place first.
  std::vector<double> candidates;
  for (const CentrelinePiece& piece : world_.centreline.pieces()) {
    if (piece.curvature_per_m != 0) continue;
    const double from = std::max(piece.s0_m - lo, -o.margin_before_m - lo);
    const double to = std::min(piece.s0_m + piece.length_m - hi, o.length_m - hi);
    for (double s = std::ceil(from); s <= to; s += 1.0) candidates.push_back(s);
  }
  std::sort(candidates.begin(), candidates.end(), [&](double p, double q) {
    return std::abs(p - options_.at_m) < std::abs(q - options_.at_m);
  });
  for (const double s : candidates) {
    // The side street and its buildings must not cross the street elsewhere (a curve bending
    // back towards it).
    const JunctionFrame f(world_.centreline, s, options_.angle_deg);
    const double w = outer_ + kFacadeFrontM + kMaxSetbackM + kMaxDepthM;
    double r0 = 0;
    for (const double side_w : {-w, w}) r0 = std::max(r0, f.RAt(-outer_ - 1.0, side_w));
    const double r1 = f.RAt(-half_, 0) + options_.length_m;
    const std::vector<Eigen::Vector2d> far = {f.Side(r0, -w), f.Side(r0, w), f.Side(r1, w),
                                              f.Side(r1, -w)};
    bool free = true;
    for (const Surface& surface : world_.surfaces) {
      if (surface.kind != SurfaceKind::kRoad && surface.kind != SurfaceKind::kSidewalk) continue;
      if (Overlap(Footprint(surface), far, 0.0)) {
        free = false;
        break;
      }
    }
    if (free) return s;
  }
  Throw(
      "side street: the street has no straight stretch of {:.0f} m (for a {} deg junction) "
      "between s = {} m and {} m with room beside it; try another seed or a longer street",
      hi - lo, options_.angle_deg, -o.margin_before_m, o.length_m);
}

void SideStreetBuilder::RemoveWhatStandsInTheWay(const JunctionFrame& f, double* x_a, double* x_b) {
  const double end_r = side_.end_r_m;
  // The side street with its pavements; the zone of its buildings; the no-parking stretch.
  const std::vector<Eigen::Vector2d> corridor = {f.Side(0, -outer_), f.Side(0, outer_),
                                                 f.Side(end_r, outer_), f.Side(end_r, -outer_)};
  const double wb = outer_ + kFacadeFrontM + kMaxSetbackM + kMaxDepthM + kClearanceM;
  double rb = 0;
  for (const double w : {-wb, wb}) rb = std::max(rb, f.RAt(-outer_, w));
  const std::vector<Eigen::Vector2d> buildings = {f.Side(rb, -wb), f.Side(rb, wb),
                                                  f.Side(end_r + 2, wb), f.Side(end_r + 2, -wb)};
  const double park_lo = f.XAt(-half_, -half_) - kNoParkingM;
  const double park_hi = f.XAt(-half_, half_) + kNoParkingM;
  *x_a = std::numeric_limits<double>::infinity();
  *x_b = -std::numeric_limits<double>::infinity();
  std::vector<bool> keep(world_.surfaces.size(), true);
  for (size_t i = 0; i < world_.surfaces.size(); ++i) {
    const Surface& s = world_.surfaces[i];
    const std::vector<Eigen::Vector2d> fp = Footprint(s);
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    double lo_x = 1e300, hi_x = -1e300;
    for (const Eigen::Vector2d& p : fp) {
      centroid += 0.25 * p;
      lo_x = std::min(lo_x, f.XOf(p));
      hi_x = std::max(hi_x, f.XOf(p));
    }
    if (f.YOf(centroid) >= 0) continue;  // the street's other side stays
    switch (s.kind) {
      case SurfaceKind::kSidewalk:
        if (Overlap(fp, corridor, 0.0)) {
          keep[i] = false;
          *x_a = std::min(*x_a, lo_x);
          *x_b = std::max(*x_b, hi_x);
        }
        break;
      case SurfaceKind::kCar:
        keep[i] = !(hi_x > park_lo && lo_x < park_hi) && !Overlap(fp, corridor, kClearanceM);
        break;
      case SurfaceKind::kFacade:
      case SurfaceKind::kWall:
      case SurfaceKind::kBackground:
      case SurfaceKind::kPole:
      case SurfaceKind::kSign:
        keep[i] = !Overlap(fp, corridor, kClearanceM) && !Overlap(fp, buildings, 0.0);
        break;
      default:
        break;
    }
  }
  EPILOC_CHECK(*x_a < *x_b, "side street: no pavement of the street at the junction");
  // The kerb faces along the removed pavement (the pavement and kerbs share the chunks' ends).
  for (size_t i = 0; i < world_.surfaces.size(); ++i) {
    const Surface& s = world_.surfaces[i];
    if (s.kind != SurfaceKind::kKerb) continue;
    const Eigen::Vector2d c = 0.5 * (s.corners_in_world[0] + s.corners_in_world[1]).head<2>();
    if (f.YOf(c) < 0 && f.XOf(c) > *x_a && f.XOf(c) < *x_b) keep[i] = false;
  }
  std::vector<int> index(world_.surfaces.size(), -1);
  std::vector<Surface> kept;
  for (size_t i = 0; i < world_.surfaces.size(); ++i) {
    if (!keep[i]) continue;
    index[i] = static_cast<int>(kept.size());
    kept.push_back(world_.surfaces[i]);
  }
  world_.surfaces = std::move(kept);
  std::vector<Marker> markers;
  for (Marker m : world_.markers) {
    if (index[m.surface] < 0) continue;
    m.surface = index[m.surface];
    markers.push_back(m);
  }
  world_.markers = std::move(markers);
}

void SideStreetBuilder::AddCornerWalls(const JunctionFrame& f) {
  // The street's buildings next to the side street show their side walls to it.
  const double near_w = outer_ + kClearanceM + 3.0;
  const size_t n = world_.surfaces.size();
  for (size_t i = 0; i < n; ++i) {
    const Surface facade = world_.surfaces[i];
    if (facade.kind != SurfaceKind::kFacade) continue;
    const Eigen::Vector2d c0 = facade.corners_in_world[0].head<2>();
    const Eigen::Vector2d c1 = facade.corners_in_world[1].head<2>();
    if (f.YOf(0.5 * (c0 + c1)) >= 0) continue;
    const Eigen::Vector2d along = (c1 - c0).normalized();
    // AddUpright's normal points away from the side it is seen from.
    const Eigen::Vector2d to_road = -facade.Normal().head<2>().normalized();
    for (const auto& [end, outward] :
         {std::make_pair(c0, Eigen::Vector2d(-along)), std::make_pair(c1, along)}) {
      const double w = (end - f.origin).dot(f.b);
      if (std::abs(w) > near_w || (end - f.origin).dot(f.a) < 0) continue;
      // Towards the side street only.
      if (outward.dot(f.b) * w > 0) continue;
      bool has_wall = false;
      for (const Surface& s : world_.surfaces) {
        if (s.kind != SurfaceKind::kWall) continue;
        for (const Eigen::Vector3d& c : s.corners_in_world) {
          has_wall = has_wall || (c.head<2>() - end).norm() < 1e-6;
        }
      }
      if (has_wall) continue;
      const double top = facade.corners_in_world[0].z(), bottom = facade.corners_in_world[3].z();
      const double depth = 0.5 * (8.0 + 14.0);  // the street's buildings are 8-14 m deep
      const int tex =
          AddTexture(WallTexture(depth, top - bottom, 0.5 * world_.options.facade_pixels_per_m,
                                 MixSeed(world_.options.seed, 9200 + i)));
      AddUpright(SurfaceKind::kWall, end - 0.5 * depth * to_road, outward, depth, bottom, top, tex);
    }
  }
}

void SideStreetBuilder::AddPavementAndKerbs(const JunctionFrame& f, double x_a, double x_b) {
  const WorldOptions& o = world_.options;
  const Centreline& street = world_.centreline;
  const int piece = street.PieceAt(side_.junction_s_m);
  const uint64_t road_seed = MixSeed(o.seed, 3), walk_seed = MixSeed(o.seed, 4);
  const RoadProfile road = o.road;
  const auto street_walk = [&](cv::Size size, double mpp, const GroundPatch& patch) {
    return SidewalkTexture(size, mpp, patch, street, road, walk_seed);
  };
  // What is left of the street's pavement on both sides of the mouth, and its kerbs.
  const double kerb_z = road.kerb_height_m;
  AddFlat(SurfaceKind::kSidewalk,
          {f.Street(x_a, -outer_), f.Street(f.XAt(-outer_, -half_), -outer_),
           f.Street(f.XAt(-half_, -half_), -half_), f.Street(x_a, -half_)},
          kerb_z, o.sidewalk_pixels_per_m, f.x, street_walk, piece);
  AddFlat(SurfaceKind::kSidewalk,
          {f.Street(f.XAt(-outer_, half_), -outer_), f.Street(x_b, -outer_), f.Street(x_b, -half_),
           f.Street(f.XAt(-half_, half_), -half_)},
          kerb_z, o.sidewalk_pixels_per_m, f.x, street_walk, piece);
  AddKerb(f.Street(x_a, -half_), f.Street(f.XAt(-half_, -half_), -half_), f.y);
  AddKerb(f.Street(f.XAt(-half_, half_), -half_), f.Street(x_b, -half_), f.y);

  // The side street: asphalt from the street's kerb line, pavements from the street's pavement
  // edge, kerbs between them; its own road coordinates for markings and pavers.
  const Centreline& line = side_.centreline;
  const std::vector<RoadStamp> stamps =
      MakeRoadStamps(0.0, line.end_s_m(), road, MixSeed(o.seed, 9002));
  const double end_r = side_.end_r_m;
  const Eigen::Vector2d along = -f.a;  // its travel direction towards the street
  AddFlat(
      SurfaceKind::kRoad,
      {f.Side(f.RAt(-half_, half_), half_), f.Side(f.RAt(-half_, -half_), -half_),
       f.Side(end_r, -half_), f.Side(end_r, half_)},
      0.0, o.road_pixels_per_m, along,
      [&](cv::Size size, double mpp, const GroundPatch& patch) {
        return RoadTexture(size, mpp, patch, line, road, stamps, {}, road_seed);
      },
      0);
  for (const double side : {-1.0, 1.0}) {
    const double w0 = side * half_, w1 = side * outer_;
    AddFlat(
        SurfaceKind::kSidewalk,
        {f.Side(f.RAt(-outer_, w0), w0), f.Side(f.RAt(-outer_, w1), w1), f.Side(end_r, w1),
         f.Side(end_r, w0)},
        kerb_z, o.sidewalk_pixels_per_m, along,
        [&](cv::Size size, double mpp, const GroundPatch& patch) {
          return SidewalkTexture(size, mpp, patch, line, road, walk_seed);
        },
        0);
    AddKerb(f.Side(f.RAt(-half_, w0), w0), f.Side(end_r, w0), -side * f.b);
  }
}

void SideStreetBuilder::AddBuildings(const JunctionFrame& f, double r_begin, double r_end) {
  const WorldOptions& o = world_.options;
  for (const double side : {-1.0, 1.0}) {
    double r = r_begin + rng_.Uniform(0, 3);
    while (r + o.min_building_width_m < r_end) {
      const double width = std::min(rng_.Uniform(o.min_building_width_m, 16.0), r_end - r);
      const double height = rng_.Uniform(o.min_building_height_m, o.max_building_height_m);
      const double setback = rng_.Uniform(0, kMaxSetbackM);
      const double depth = rng_.Uniform(8.0, kMaxDepthM);
      const bool build = rng_.Bernoulli(options_.building_probability);
      const uint64_t seed = MixSeed(o.seed, 9300 + static_cast<uint64_t>(rng_.Next() % 100000));
      if (build) {
        const double w = side * (half_ + kFacadeFrontM + setback);
        const Eigen::Vector2d to_axis = -side * f.b;
        std::vector<MarkerPlacement> placements;
        const double bottom = -0.06, top = height;  // bottom as the street's buildings
        const int tex =
            AddTexture(FacadeTexture(width, top - bottom, o.facade_pixels_per_m,
                                     o.markers_per_facade, o.marker_square_m, seed, &placements));
        const int facade = AddUpright(SurfaceKind::kFacade, f.Side(r + 0.5 * width, w), to_axis,
                                      width, bottom, top, tex);
        for (const MarkerPlacement& m : placements) {
          Marker marker;
          marker.surface = facade;
          marker.square_m = m.square_m;
          marker.position_in_world =
              world_.surfaces[facade].PointAt(m.corner_uv_m.x(), m.corner_uv_m.y());
          world_.markers.push_back(marker);
        }
        for (const int end : {0, 1}) {
          const Eigen::Vector2d corner = f.Side(r + end * width, w);
          const int wall_tex = AddTexture(
              WallTexture(depth, top - bottom, 0.5 * o.facade_pixels_per_m, seed + 1 + end));
          AddUpright(SurfaceKind::kWall, corner - 0.5 * depth * to_axis,
                     end ? Eigen::Vector2d(f.a) : Eigen::Vector2d(-f.a), depth, bottom, top,
                     wall_tex);
        }
      }
      r += width + rng_.Uniform(1.0, 5.0);  // gaps keep neighbouring walls apart
    }
  }
}

void SideStreetBuilder::Build() {
  options_.Check();
  side_.junction_s_m = FindJunction();
  side_.angle_deg = options_.angle_deg;
  side_.length_m = options_.length_m;
  const JunctionFrame f(world_.centreline, side_.junction_s_m, options_.angle_deg);
  side_.junction_in_world = f.origin;
  side_.away = f.a;
  side_.end_r_m = f.RAt(-half_, 0) + options_.length_m;
  double lo = 0, hi = 0;
  StraightExtent(&lo, &hi);
  side_.straight_from_s_m = side_.junction_s_m + lo;
  side_.straight_to_s_m = side_.junction_s_m + hi;
  CentrelinePiece axis;
  axis.s0_m = 0.0;
  axis.length_m = side_.end_r_m + 1.0 + outer_;
  axis.start_in_world = f.Side(side_.end_r_m + 1.0, 0.0);
  axis.start_yaw_rad = std::atan2(-f.a.y(), -f.a.x());
  side_.centreline = Centreline({axis});

  double x_a = 0, x_b = 0;
  RemoveWhatStandsInTheWay(f, &x_a, &x_b);
  AddCornerWalls(f);
  AddPavementAndKerbs(f, x_a, x_b);
  double r_begin = 0;
  const double reach = outer_ + kStreetBuildingsReachM;
  const double wb = outer_ + kFacadeFrontM + kMaxSetbackM + kMaxDepthM;
  for (const double w : {-wb, wb}) r_begin = std::max(r_begin, f.RAt(-reach, w));
  AddBuildings(f, r_begin, side_.end_r_m - 2.0);
  world_.side_street = side_;
}

}  // namespace

void SideStreetOptions::Check() const {
  EPILOC_CHECK(std::isfinite(angle_deg) && angle_deg >= 60 && angle_deg <= 120,
               "side street options: angle_deg = {} must be in [60, 120]", angle_deg);
  EPILOC_CHECK(std::isfinite(at_m), "side street options: at_m is not finite");
  EPILOC_CHECK(std::isfinite(length_m) && length_m >= 40,
               "side street options: length_m = {} must be at least 40 m", length_m);
  EPILOC_CHECK(building_probability >= 0 && building_probability <= 1,
               "side street options: building_probability must be in [0, 1]");
}

bool SideStreet::OnAsphalt(const World& world,
                           const Eigen::Vector2d& point,
                           double margin_m) const {
  const double half = world.options.road.asphalt_half_width_m();
  if (std::abs(world.centreline.ToRoad(point).d_m) <= half - margin_m) return true;
  const Eigen::Vector2d v = point - junction_in_world;
  const Eigen::Vector2d b(-away.y(), away.x());
  const double r = v.dot(away);
  return r >= 0 && r <= end_r_m && std::abs(v.dot(b)) <= half - margin_m;
}

void AddSideStreet(World* world) {
  EPILOC_CHECK(world != nullptr, "side street: no world");
  SideStreetBuilder(world).Build();
}

}  // namespace epiloc
