#include "epiloc/synth/world.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <exception>
#include <functional>
#include <memory>
#include <thread>

#include "epiloc/core/error.h"
#include "vegetation.h"

namespace epiloc {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kNearGroundZ = -0.02;  // below the road so the two never tie in depth
constexpr double kFarGroundZ = -0.06;   // below the near ground
constexpr double kBuildingBottomZ = -0.06;
constexpr double kFacadeFront = 3.0;  // fronts stand at least this far behind the kerb, metres

Eigen::Vector3d Lift(const Eigen::Vector2d& p, double z) {
  return Eigen::Vector3d(p.x(), p.y(), z);
}

// Builds the world piece by piece; textures are generated later, in parallel, by `jobs`.
class WorldBuilder {
 public:
  explicit WorldBuilder(const WorldOptions& options) : rng_(MixSeed(options.seed, 1)) {
    world_.options = options;
  }

  World Build();

 private:
  void MakeCentreline();
  void AddRoad();
  void AddGround();
  void AddBuildings(int side);
  void AddBackground(int side);
  void AddPoles(int side);
  void AddCars(int side);
  void RunJobs();

  double SBegin() const { return -world_.options.margin_before_m; }
  double SEnd() const { return world_.options.length_m + world_.options.margin_after_m; }
  uint64_t NextSeed() { return MixSeed(world_.options.seed, 1000 + jobs_.size()); }

  int AddTexture(std::function<Texture()> job) {
    jobs_.push_back(std::move(job));
    return static_cast<int>(jobs_.size()) - 1;
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
  // A vertical rectangle of `width` centred on `centre` (horizontal), from z0 to z1, seen from the
  // side `outward` points to: texture u runs left to right and v downwards for that viewer.
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
  // Smallest |d| along the straight segment between (s0, d) and (s1, d) of the centreline.
  double MinChordOffset(double s0, double s1, double d) const {
    const Eigen::Vector2d a = world_.centreline.PointAt(s0, d),
                          b = world_.centreline.PointAt(s1, d);
    double min_d = 1e9;
    for (int i = 0; i <= 8; ++i) {
      min_d = std::min(min_d, std::abs(world_.centreline.ToRoad(a + (b - a) * i / 8.0).d_m));
    }
    return min_d;
  }

  World world_;
  Rng rng_;
  std::vector<std::function<Texture()>> jobs_;
  // Facade surface and the markers its texture job reports.
  std::vector<std::pair<int, std::shared_ptr<std::vector<MarkerPlacement>>>> marker_jobs_;
};

void WorldBuilder::MakeCentreline() {
  const WorldOptions& o = world_.options;
  const double yaw0 = rng_.Uniform(0, 2 * M_PI);
  std::vector<CentrelinePiece> pieces;
  CentrelinePiece first;
  first.s0_m = SBegin();
  first.start_yaw_rad = yaw0;
  first.start_in_world = SBegin() * Eigen::Vector2d(std::cos(yaw0), std::sin(yaw0));
  first.length_m = o.margin_before_m + rng_.Uniform(0.5 * o.min_straight_m, o.max_straight_m);
  pieces.push_back(first);
  bool arc = true;
  double turned = 0;
  while (pieces.back().s0_m + pieces.back().length_m < SEnd()) {
    const CentrelinePiece& prev = pieces.back();
    CentrelinePiece next;
    next.s0_m = prev.s0_m + prev.length_m;
    Centreline so_far(pieces);
    next.start_in_world = so_far.PointAt(next.s0_m);
    next.start_yaw_rad = so_far.YawAt(next.s0_m);
    if (arc) {
      const double radius = rng_.Uniform(o.min_radius_m, o.max_radius_m);
      double turn = rng_.Uniform(15.0, std::max(15.0, o.max_turn_deg)) * kDeg;
      if (rng_.Bernoulli(0.5)) turn = -turn;
      if (std::abs(turned + turn) > 100 * kDeg) turn = -turn;  // never curl back
      turned += turn;
      next.curvature_per_m = (turn > 0 ? 1.0 : -1.0) / radius;
      next.length_m = std::abs(turn) * radius;
    } else {
      next.length_m = rng_.Uniform(o.min_straight_m, o.max_straight_m);
    }
    arc = !arc;
    pieces.push_back(next);
  }
  pieces.back().length_m = SEnd() - pieces.back().s0_m;
  world_.centreline = Centreline(pieces);
}

void WorldBuilder::AddRoad() {
  const WorldOptions& o = world_.options;
  const RoadProfile& road = o.road;
  const double half = road.asphalt_half_width_m(), outer = half + road.sidewalk_width_m;
  for (double s = 20.0 + rng_.Uniform(0, 40); s < o.length_m - 10; s += rng_.Uniform(70, 140)) {
    world_.crossings_s_m.push_back(s);
  }
  auto stamps = std::make_shared<std::vector<RoadStamp>>(
      MakeRoadStamps(SBegin(), SEnd(), road, MixSeed(o.seed, 2)));
  const Centreline& cl = world_.centreline;
  const uint64_t road_seed = MixSeed(o.seed, 3), walk_seed = MixSeed(o.seed, 4);
  for (int i = 0; i < static_cast<int>(cl.pieces().size()); ++i) {
    const CentrelinePiece& piece = cl.pieces()[i];
    // Chords of curved pieces stay within 2 cm of the arc at the pavement's outer edge.
    const double radius =
        std::abs(piece.curvature_per_m) > 0 ? 1.0 / std::abs(piece.curvature_per_m) : 1e9;
    const double max_chunk = std::min(8.0, std::sqrt(8.0 * (radius + outer) * 0.02));
    const int n = static_cast<int>(std::ceil(piece.length_m / max_chunk));
    for (int k = 0; k < n; ++k) {
      const double sa = piece.s0_m + piece.length_m * k / n;
      const double sb = piece.s0_m + piece.length_m * (k + 1) / n;
      const Eigen::Vector2d t = (cl.PointAt(sb) - cl.PointAt(sa)).normalized();
      const Eigen::Vector2d l(-t.y(), t.x());
      // One quad between lateral offsets d0 < d1 at height z, textured by `make`.
      const auto add_strip = [&](SurfaceKind kind, double d0, double d1, double z, double ppm,
                                 auto make) {
        const std::array<Eigen::Vector2d, 4> c = {cl.PointAt(sa, d0), cl.PointAt(sb, d0),
                                                  cl.PointAt(sb, d1), cl.PointAt(sa, d1)};
        Eigen::Vector2d lo(1e18, 1e18), hi(-1e18, -1e18);
        for (const auto& p : c) {
          const Eigen::Vector2d uv(p.dot(t), p.dot(l));
          lo = lo.cwiseMin(uv);
          hi = hi.cwiseMax(uv);
        }
        GroundPatch patch{lo.x() * t + lo.y() * l, t, l, i};
        const cv::Size size(static_cast<int>(std::ceil((hi.x() - lo.x()) * ppm)) + 1,
                            static_cast<int>(std::ceil((hi.y() - lo.y()) * ppm)) + 1);
        const int tex = AddTexture([=] { return make(size, 1.0 / ppm, patch); });
        AddSurface(kind, {Lift(c[0], z), Lift(c[1], z), Lift(c[2], z), Lift(c[3], z)}, tex,
                   Lift(patch.origin_in_world, z), Lift(t, 0), Lift(l, 0));
      };
      const Centreline centreline = cl;
      const std::vector<double> crossings = world_.crossings_s_m;
      add_strip(SurfaceKind::kRoad, -half, half, 0.0, o.road_pixels_per_m,
                [=](cv::Size size, double mpp, const GroundPatch& patch) {
                  return RoadTexture(size, mpp, patch, centreline, road, *stamps, crossings,
                                     road_seed);
                });
      for (const int side : {-1, 1}) {
        const double d0 = side < 0 ? -outer : half, d1 = side < 0 ? -half : outer;
        add_strip(SurfaceKind::kSidewalk, d0, d1, road.kerb_height_m, o.sidewalk_pixels_per_m,
                  [=](cv::Size size, double mpp, const GroundPatch& patch) {
                    return SidewalkTexture(size, mpp, patch, centreline, road, walk_seed);
                  });
        // Kerb face between the road and the pavement edge, seen from the road.
        const Eigen::Vector2d a = cl.PointAt(sa, side * half), b = cl.PointAt(sb, side * half);
        const Eigen::Vector2d outward = (side < 0 ? 1.0 : -1.0) * l;
        const double width = (b - a).norm();
        const int tex = AddTexture(
            [=, seed = NextSeed()] { return KerbTexture(width, road.kerb_height_m, 100.0, seed); });
        AddUpright(SurfaceKind::kKerb, 0.5 * (a + b), outward, width, 0.0, road.kerb_height_m, tex);
      }
    }
  }
}

void WorldBuilder::AddGround() {
  const Centreline& cl = world_.centreline;
  Eigen::Vector2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (double s = SBegin(); s <= SEnd(); s += 2.0) {
    lo = lo.cwiseMin(cl.PointAt(s));
    hi = hi.cwiseMax(cl.PointAt(s));
  }
  const double ppm = world_.options.ground_pixels_per_m;
  const auto add = [&](double margin, double z, double pixels_per_m, uint64_t seed) {
    const Eigen::Vector2d a = lo - Eigen::Vector2d::Constant(margin);
    const Eigen::Vector2d b = hi + Eigen::Vector2d::Constant(margin);
    const cv::Size size(static_cast<int>(std::ceil((b.x() - a.x()) * pixels_per_m)),
                        static_cast<int>(std::ceil((b.y() - a.y()) * pixels_per_m)));
    const GroundPatch patch{a, Eigen::Vector2d::UnitX(), Eigen::Vector2d::UnitY(), -1};
    const int tex =
        AddTexture([=] { return GroundTexture(size, 1.0 / pixels_per_m, patch, seed); });
    AddSurface(SurfaceKind::kGround,
               {Lift(a, z), Lift(Eigen::Vector2d(b.x(), a.y()), z), Lift(b, z),
                Lift(Eigen::Vector2d(a.x(), b.y()), z)},
               tex, Lift(a, z), Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY());
  };
  add(90.0, kNearGroundZ, ppm, MixSeed(world_.options.seed, 5));
  add(900.0, kFarGroundZ, 0.25, MixSeed(world_.options.seed, 6));
}

void WorldBuilder::AddBuildings(int side) {
  const WorldOptions& o = world_.options;
  const Centreline& cl = world_.centreline;
  const double front = o.road.asphalt_half_width_m() + kFacadeFront;
  // The far side wall of the previous building waits until the next building is known: between
  // adjacent buildings only the wall of the one standing closer to the road can be seen.
  std::function<void()> pending_wall;
  double prev_setback = -1;
  double s = SBegin() + rng_.Uniform(0, 4);
  while (s < SEnd() - o.min_building_width_m) {
    bool adjacent = prev_setback >= 0;
    if (rng_.Bernoulli(o.gap_probability)) {
      s += rng_.Uniform(2.0, o.max_gap_m);
      adjacent = false;
    }
    double width = rng_.Uniform(o.min_building_width_m, o.max_building_width_m);
    const double height = rng_.Uniform(o.min_building_height_m, o.max_building_height_m);
    const double setback = rng_.Uniform(0, o.max_setback_m);
    const double depth = rng_.Uniform(8, 14);
    const double d = side * (front + setback);
    while (width > o.min_building_width_m && MinChordOffset(s, s + width, d) < front - 0.8) {
      width *= 0.85;
    }
    const Eigen::Vector2d a = cl.PointAt(s, d), b = cl.PointAt(s + width, d);
    const Eigen::Vector2d along = (b - a).normalized();
    const Eigen::Vector2d to_road = side * Eigen::Vector2d(along.y(), -along.x());
    const double chord = (b - a).norm(), top = height, bottom = kBuildingBottomZ;
    auto markers = std::make_shared<std::vector<MarkerPlacement>>();
    const int tex = AddTexture([=, seed = NextSeed()] {
      return FacadeTexture(chord, top - bottom, o.facade_pixels_per_m, o.markers_per_facade,
                           o.marker_square_m, seed, markers.get());
    });
    const int facade =
        AddUpright(SurfaceKind::kFacade, 0.5 * (a + b), to_road, chord, bottom, top, tex);
    marker_jobs_.emplace_back(facade, markers);
    const auto wall = [=](const Eigen::Vector2d& corner, const Eigen::Vector2d& outward) {
      const int wall_tex = AddTexture([=, seed = NextSeed()] {
        return WallTexture(depth, top - bottom, 0.5 * o.facade_pixels_per_m, seed);
      });
      AddUpright(SurfaceKind::kWall, corner - 0.5 * depth * to_road, outward, depth, bottom, top,
                 wall_tex);
    };
    if (pending_wall && (!adjacent || prev_setback < setback)) pending_wall();
    if (!adjacent || setback < prev_setback) wall(a, -along);
    pending_wall = [=] { wall(b, along); };
    prev_setback = setback;
    s += width;
  }
  if (pending_wall) pending_wall();
}

void WorldBuilder::AddBackground(int side) {
  const WorldOptions& o = world_.options;
  const Centreline& cl = world_.centreline;
  const double behind = o.road.asphalt_half_width_m() + kFacadeFront + o.max_setback_m;
  for (double s = SBegin() + rng_.Uniform(0, 10); s < SEnd();) {
    double width = rng_.Uniform(15, 35);
    const double height = rng_.Uniform(12, 30);
    const double d = side * (behind + rng_.Uniform(16, 26));
    while (width > 10 && MinChordOffset(s, s + width, d) < behind + 14) width *= 0.8;
    if (width <= 10) {
      s += 10;
      continue;
    }
    const Eigen::Vector2d a = cl.PointAt(s, d), b = cl.PointAt(s + width, d);
    const Eigen::Vector2d along = (b - a).normalized();
    const Eigen::Vector2d to_road = side * Eigen::Vector2d(along.y(), -along.x());
    const double chord = (b - a).norm();
    const int tex = AddTexture([=, seed = NextSeed()] {
      return BackgroundTexture(chord, height - kBuildingBottomZ, 10.0, seed);
    });
    AddUpright(SurfaceKind::kBackground, 0.5 * (a + b), to_road, chord, kBuildingBottomZ, height,
               tex);
    s += width + rng_.Uniform(0, 6);
  }
}

void WorldBuilder::AddPoles(int side) {
  const WorldOptions& o = world_.options;
  const Centreline& cl = world_.centreline;
  const double d = side * (o.road.asphalt_half_width_m() + 0.6), z0 = o.road.kerb_height_m;
  constexpr double kPoleWidth = 0.14, kPoleHeight = 5.5;
  for (double s = SBegin() + rng_.Uniform(0, o.pole_spacing_m); s < SEnd();
       s += o.pole_spacing_m * rng_.Uniform(0.7, 1.3)) {
    const Eigen::Vector2d p = cl.PointAt(s, d), t = cl.TangentAt(s);
    const Eigen::Vector2d l(-t.y(), t.x());
    const int metal = AddTexture(
        [seed = NextSeed()] { return MetalTexture(kPoleWidth, kPoleHeight, 100.0, seed); });
    for (const Eigen::Vector2d& n : {t, l, Eigen::Vector2d(-t), Eigen::Vector2d(-l)}) {
      AddUpright(SurfaceKind::kPole, p + 0.5 * kPoleWidth * n, n, kPoleWidth, z0, z0 + kPoleHeight,
                 metal);
    }
    if (!rng_.Bernoulli(0.65)) continue;
    // A sign facing the drivers of this side's lane (or, on the far side, either way).
    const Eigen::Vector2d facing = (side < 0 || rng_.Bernoulli(0.5)) ? Eigen::Vector2d(-t) : t;
    const double w = rng_.Uniform(0.5, 0.85), h = rng_.Uniform(0.5, 0.85);
    const double zb = z0 + rng_.Uniform(1.9, 2.6);
    const Eigen::Vector2d centre = p + (0.5 * kPoleWidth + 0.02) * facing;
    const int front = AddTexture([=, seed = NextSeed()] { return SignTexture(w, h, 150.0, seed); });
    AddUpright(SurfaceKind::kSign, centre, facing, w, zb, zb + h, front);
    const int back = AddTexture([=, seed = NextSeed()] { return MetalTexture(w, h, 100.0, seed); });
    AddUpright(SurfaceKind::kSign, centre - 0.015 * facing, -facing, w, zb, zb + h, back);
  }
}

void WorldBuilder::AddCars(int side) {
  const WorldOptions& o = world_.options;
  const Centreline& cl = world_.centreline;
  const double d_centre = side * (o.road.lane_width_m + 0.5 * o.road.parking_width_m);
  for (double s = SBegin() + 3; s < SEnd() - 3; s += 6.0) {
    bool free = true;
    for (const double sc : world_.crossings_s_m) free = free && (s < sc - 10 || s > sc + 14);
    if (!free) continue;
    world_.parking_slots.push_back({s, side, -1});
    if (!rng_.Bernoulli(o.car_probability)) continue;
    world_.parking_slots.back().first_surface = static_cast<int>(world_.surfaces.size());
    const double length = rng_.Uniform(3.9, 4.8), width = rng_.Uniform(1.7, 1.9);
    const double height = rng_.Uniform(1.4, 1.6), z0 = 0.03;
    const double sc = s + rng_.Uniform(-0.5, 0.5);
    const Eigen::Vector2d c = cl.PointAt(sc, d_centre + rng_.Uniform(-0.15, 0.15));
    const double yaw = cl.YawAt(sc) + rng_.Uniform(-2, 2) * kDeg + (side > 0 ? M_PI : 0.0);
    const Eigen::Vector2d fwd(std::cos(yaw), std::sin(yaw)), left(-fwd.y(), fwd.x());
    const cv::Vec3b paint = CarPaint(rng_);
    const auto tex = [&](int face, double w, double h) {
      return AddTexture(
          [=, seed = NextSeed()] { return CarTexture(face, w, h, 60.0, paint, seed); });
    };
    AddUpright(SurfaceKind::kCar, c + 0.5 * width * left, left, length, z0, z0 + height,
               tex(0, length, height));
    AddUpright(SurfaceKind::kCar, c - 0.5 * width * left, -left, length, z0, z0 + height,
               tex(0, length, height));
    AddUpright(SurfaceKind::kCar, c + 0.5 * length * fwd, fwd, width, z0, z0 + height,
               tex(1, width, height));
    AddUpright(SurfaceKind::kCar, c - 0.5 * length * fwd, -fwd, width, z0, z0 + height,
               tex(2, width, height));
    const Eigen::Vector3d origin = Lift(c - 0.5 * length * fwd - 0.5 * width * left, z0 + height);
    const Eigen::Vector3d u = Lift(fwd, 0), v = Lift(left, 0);
    AddSurface(SurfaceKind::kCar,
               {origin, origin + length * u, origin + length * u + width * v, origin + width * v},
               tex(3, length, width), origin, u, v);
  }
}

void WorldBuilder::RunJobs() {
  world_.textures.resize(jobs_.size());
  std::atomic<size_t> next{0};
  std::vector<std::exception_ptr> errors(jobs_.size());
  const auto work = [&] {
    for (size_t i = next++; i < jobs_.size(); i = next++) {
      try {
        world_.textures[i] = jobs_[i]();
        world_.textures[i].BuildPyramid();
      } catch (...) {
        errors[i] = std::current_exception();
      }
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < world_.options.num_threads; ++t) threads.emplace_back(work);
  work();
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
  jobs_.clear();
}

World WorldBuilder::Build() {
  MakeCentreline();
  AddGround();
  AddRoad();
  for (const int side : {-1, 1}) {
    AddBuildings(side);
    if (world_.options.background_buildings) AddBackground(side);
    AddPoles(side);
    AddCars(side);
  }
  RunJobs();
  for (const auto& [surface, placements] : marker_jobs_) {
    for (const MarkerPlacement& m : *placements) {
      Marker marker;
      marker.surface = surface;
      marker.square_m = m.square_m;
      marker.position_in_world =
          world_.surfaces[surface].PointAt(m.corner_uv_m.x(), m.corner_uv_m.y());
      world_.markers.push_back(marker);
    }
  }
  // Last, from its own random stream: without vegetation the world is the same as before.
  if (world_.options.vegetation.fraction > 0) AddVegetation(&world_);
  return std::move(world_);
}

}  // namespace

const char* SurfaceKindName(SurfaceKind kind) {
  switch (kind) {
    case SurfaceKind::kGround:
      return "ground";
    case SurfaceKind::kRoad:
      return "road";
    case SurfaceKind::kSidewalk:
      return "sidewalk";
    case SurfaceKind::kKerb:
      return "kerb";
    case SurfaceKind::kFacade:
      return "facade";
    case SurfaceKind::kWall:
      return "wall";
    case SurfaceKind::kBackground:
      return "background";
    case SurfaceKind::kPole:
      return "pole";
    case SurfaceKind::kSign:
      return "sign";
    case SurfaceKind::kCar:
      return "car";
    case SurfaceKind::kHedge:
      return "hedge";
    case SurfaceKind::kTreeTrunk:
      return "tree_trunk";
    case SurfaceKind::kTreeCrown:
      return "tree_crown";
  }
  return "?";
}

Eigen::Vector2d Surface::TextureCoordinates(const Eigen::Vector3d& point_in_world) const {
  const Eigen::Vector3d v = point_in_world - texture_origin_in_world;
  return Eigen::Vector2d(v.dot(u_axis), v.dot(v_axis));
}

bool Surface::Contains(const Eigen::Vector3d& point_in_world, double tol_m) const {
  const Eigen::Vector2d p = TextureCoordinates(point_in_world);
  std::array<Eigen::Vector2d, 4> c;
  for (int i = 0; i < 4; ++i) c[i] = TextureCoordinates(corners_in_world[i]);
  double area = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d& a = c[i];
    const Eigen::Vector2d& b = c[(i + 1) % 4];
    area += a.x() * b.y() - a.y() * b.x();
  }
  const double orientation = area >= 0 ? 1.0 : -1.0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d e = c[(i + 1) % 4] - c[i];
    const Eigen::Vector2d q = p - c[i];
    if (orientation * (e.x() * q.y() - e.y() * q.x()) < -tol_m * e.norm()) return false;
  }
  return true;
}

Eigen::Vector3d World::RoadPoint(double s_m, double d_m) const {
  return Lift(centreline.PointAt(s_m, d_m), RoadHeight());
}

void WorldOptions::Check() const {
  const auto positive = [](double v, const char* name) {
    EPILOC_CHECK(std::isfinite(v) && v > 0, "world options: {} = {} must be positive", name, v);
  };
  positive(length_m, "length_m");
  CheckGeodetic(origin, "world options: origin");
  EPILOC_CHECK(margin_before_m >= 0 && margin_after_m >= 0,
               "world options: margins must not be negative");
  positive(min_straight_m, "min_straight_m");
  EPILOC_CHECK(max_straight_m >= min_straight_m, "world options: max_straight_m < min_straight_m");
  // The pavement on the inside of the tightest curve keeps 5 m from the curve's centre.
  const double min_radius = road.asphalt_half_width_m() + road.sidewalk_width_m + 5.0;
  EPILOC_CHECK(min_radius_m >= min_radius, "world options: min_radius_m = {} must be >= {} m",
               min_radius_m, min_radius);
  EPILOC_CHECK(max_radius_m >= min_radius_m, "world options: max_radius_m < min_radius_m");
  EPILOC_CHECK(max_turn_deg >= 0 && max_turn_deg <= 90,
               "world options: max_turn_deg = {} must be in [0, 90]", max_turn_deg);
  positive(road.lane_width_m, "road.lane_width_m");
  positive(road.parking_width_m, "road.parking_width_m");
  EPILOC_CHECK(road.sidewalk_width_m >= kFacadeFront + max_setback_m,
               "world options: road.sidewalk_width_m must reach the building fronts ({} m)",
               kFacadeFront + max_setback_m);
  positive(road.kerb_height_m, "road.kerb_height_m");
  positive(min_building_width_m, "min_building_width_m");
  EPILOC_CHECK(max_building_width_m >= min_building_width_m,
               "world options: max_building_width_m < min_building_width_m");
  EPILOC_CHECK(min_building_height_m >= 5, "world options: min_building_height_m must be >= 5");
  EPILOC_CHECK(max_building_height_m >= min_building_height_m,
               "world options: max_building_height_m < min_building_height_m");
  EPILOC_CHECK(max_setback_m >= 0, "world options: max_setback_m must not be negative");
  EPILOC_CHECK(gap_probability >= 0 && gap_probability <= 1,
               "world options: gap_probability must be in [0, 1]");
  EPILOC_CHECK(max_gap_m >= 2, "world options: max_gap_m must be >= 2");
  positive(pole_spacing_m, "pole_spacing_m");
  EPILOC_CHECK(car_probability >= 0 && car_probability <= 1,
               "world options: car_probability must be in [0, 1]");
  EPILOC_CHECK(markers_per_facade >= 0, "world options: markers_per_facade must not be negative");
  positive(marker_square_m, "marker_square_m");
  positive(facade_pixels_per_m, "facade_pixels_per_m");
  positive(road_pixels_per_m, "road_pixels_per_m");
  positive(sidewalk_pixels_per_m, "sidewalk_pixels_per_m");
  positive(ground_pixels_per_m, "ground_pixels_per_m");
  EPILOC_CHECK(num_threads >= 1, "world options: num_threads must be >= 1");
  vegetation.Check();
  if (side_street.enabled) side_street.Check();
}

World BuildWorld(const WorldOptions& options) {
  options.Check();
  World world = WorldBuilder(options).Build();
  if (options.side_street.enabled) AddSideStreet(&world);
  return world;
}

}  // namespace epiloc
