// Hedges and tree rows along stretches of the synthetic street, with periodic textures.
#include "vegetation.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "epiloc/synth/texture.h"

namespace epiloc {
namespace {

// As the facades: leaves of 3-8 cm stay sharp from 5 m on at the survey camera's focal length.
constexpr double kPixelsPerM = 48.0;
// Cross-section, lateral offsets from the asphalt's edge (the kerb), metres. Poles stand at 0.6 and
// their signs reach 1.05; building fronts start at 3.0 (world.cc).
constexpr double kTrunkD = 1.2;
constexpr double kHedgeFrontD = 1.7, kHedgeBackD = 2.5;
constexpr double kHedgeHeight = 1.1;  // below the cameras (1.5-1.6 m): they see over it
constexpr double kTrunkWidth = 0.3, kCrownBottom = 2.4, kCrownTop = 5.2;
// 2.8 m wide crowns reach from 0.2 m over the parking strip (above the parked cars' 1.5 m roofs)
// to 2.6 m, short of the building fronts.
constexpr double kCrownWidth = 2.8;
// Chords of at most 4 m stay within 3.5 cm of an arc of the narrowest radius (60 m).
constexpr double kMaxChunkM = 4.0;

Eigen::Vector3d Lift(const Eigen::Vector2d& p, double z) {
  return Eigen::Vector3d(p.x(), p.y(), z);
}

class VegetationBuilder {
 public:
  explicit VegetationBuilder(World* world)
      : world_(world),
        o_(world->options),
        v_(world->options.vegetation),
        rng_(MixSeed(world->options.seed, 60)) {
    period_px_ = std::max(4, static_cast<int>(std::lround(v_.foliage_period_m * kPixelsPerM)));
    mpp_ = v_.foliage_period_m / period_px_;
  }

  void Build();

 private:
  int AddTexture(double width_m, double height_m, bool bark, const cv::Vec3b& bgr) {
    const cv::Size size(static_cast<int>(std::ceil(width_m / mpp_)) + 2,
                        static_cast<int>(std::ceil(height_m / mpp_)) + 2);
    Texture t = VegetationTexture(size, period_px_, mpp_, bark, bgr, rng_.Next());
    t.BuildPyramid();
    world_->textures.push_back(std::move(t));
    return static_cast<int>(world_->textures.size()) - 1;
  }
  void AddSurface(SurfaceKind kind,
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
    world_->surfaces.push_back(s);
  }
  // A vertical rectangle of `width` centred on `centre`, from z0 to z1, facing `outward`.
  void AddUpright(SurfaceKind kind,
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
    AddSurface(
        kind,
        {origin, origin + width * right, origin + width * right + h * down, origin + h * down},
        texture, origin, right, down);
  }
  // A horizontal square of side `width` centred on `centre` at height z, sides along t and l.
  void AddFlat(SurfaceKind kind,
               const Eigen::Vector2d& centre,
               const Eigen::Vector2d& t,
               double width,
               double z,
               int texture) {
    const Eigen::Vector2d l(-t.y(), t.x());
    const Eigen::Vector3d u = Lift(t, 0), v = Lift(l, 0);
    const Eigen::Vector3d origin = Lift(centre - 0.5 * width * (t + l), z);
    AddSurface(kind, {origin, origin + width * u, origin + width * (u + v), origin + width * v},
               texture, origin, u, v);
  }
  void AddHedge(int side, double s0, double s1);
  void AddTrees(int side, double s0, double s1, const std::vector<double>& poles_s);

  World* world_;
  const WorldOptions& o_;
  const VegetationOptions& v_;
  Rng rng_;
  int period_px_ = 24;
  double mpp_ = 0.02;
  int hedge_side_ = -1, hedge_top_ = -1, crown_ = -1, crown_bottom_ = -1, bark_ = -1;
};

void VegetationBuilder::AddHedge(int side, double s0, double s1) {
  const Centreline& cl = world_->centreline;
  const double edge = o_.road.asphalt_half_width_m();
  const double d_front = side * (edge + kHedgeFrontD), d_back = side * (edge + kHedgeBackD);
  const double z0 = o_.road.kerb_height_m, z1 = z0 + kHedgeHeight;
  const double period = v_.foliage_period_m;
  const int n = static_cast<int>(std::ceil((s1 - s0) / kMaxChunkM));
  double along = 0;  // chord length so far: the texture continues from chunk to chunk
  for (int k = 0; k < n; ++k) {
    const double sa = s0 + (s1 - s0) * k / n, sb = s0 + (s1 - s0) * (k + 1) / n;
    const Eigen::Vector2d a = cl.PointAt(sa, d_front), b = cl.PointAt(sb, d_front);
    const Eigen::Vector2d a_back = cl.PointAt(sa, d_back), b_back = cl.PointAt(sb, d_back);
    const Eigen::Vector3d u = Lift((b - a).normalized(), 0);
    const Eigen::Vector3d out(side * -u.y(), side * u.x(), 0.0);  // away from the road
    const double phase = std::fmod(along, period);
    const Eigen::Vector3d front_origin = Lift(a, z1) - phase * u;
    AddSurface(SurfaceKind::kHedge, {Lift(a, z1), Lift(b, z1), Lift(b, z0), Lift(a, z0)},
               hedge_side_, front_origin, u, -Eigen::Vector3d::UnitZ());
    // The top's texture starts a period before the front edge: the chunk's trapezoid stays inside.
    AddSurface(SurfaceKind::kHedge, {Lift(a, z1), Lift(b, z1), Lift(b_back, z1), Lift(a_back, z1)},
               hedge_top_, front_origin - period * out, u, out);
    along += (b - a).norm();
  }
  for (const double s : {s0, s1}) {
    const Eigen::Vector2d front = cl.PointAt(s, d_front), back = cl.PointAt(s, d_back);
    const Eigen::Vector2d t = cl.TangentAt(s);
    AddUpright(SurfaceKind::kHedge, 0.5 * (front + back), s == s0 ? Eigen::Vector2d(-t) : t,
               (back - front).norm(), z0, z1, hedge_side_);
  }
}

void VegetationBuilder::AddTrees(int side,
                                 double s0,
                                 double s1,
                                 const std::vector<double>& poles_s) {
  const Centreline& cl = world_->centreline;
  const double d = side * (o_.road.asphalt_half_width_m() + kTrunkD);
  const double z0 = o_.road.kerb_height_m;
  const int n = static_cast<int>(std::floor((s1 - s0) / v_.tree_spacing_m));
  // Evenly spaced, centred in the stretch.
  const double first = 0.5 * (s0 + s1) - 0.5 * (n - 1) * v_.tree_spacing_m;
  for (int k = 0; k < n; ++k) {
    const double s = first + k * v_.tree_spacing_m;
    // A pole (with its sign) under the crown would pierce it: that tree is missing.
    bool clear = true;
    for (const double p : poles_s) clear = clear && std::abs(p - s) > 0.5 * kCrownWidth + 0.2;
    if (!clear) continue;
    const Eigen::Vector2d p = cl.PointAt(s, d), t = cl.TangentAt(s);
    const Eigen::Vector2d l(-t.y(), t.x());
    for (const Eigen::Vector2d& dir : {t, l, Eigen::Vector2d(-t), Eigen::Vector2d(-l)}) {
      AddUpright(SurfaceKind::kTreeTrunk, p + 0.5 * kTrunkWidth * dir, dir, kTrunkWidth, z0,
                 z0 + kCrownBottom, bark_);
      AddUpright(SurfaceKind::kTreeCrown, p + 0.5 * kCrownWidth * dir, dir, kCrownWidth,
                 z0 + kCrownBottom, z0 + kCrownTop, crown_);
    }
    AddFlat(SurfaceKind::kTreeCrown, p, t, kCrownWidth, z0 + kCrownBottom, crown_bottom_);
    AddFlat(SurfaceKind::kTreeCrown, p, t, kCrownWidth, z0 + kCrownTop, crown_);
  }
}

void VegetationBuilder::Build() {
  const double period = v_.foliage_period_m;
  hedge_side_ = AddTexture(kMaxChunkM + 2 * period, kHedgeHeight, false, cv::Vec3b(35, 80, 40));
  hedge_top_ = AddTexture(kMaxChunkM + 2 * period, kHedgeBackD - kHedgeFrontD + 3 * period, false,
                          cv::Vec3b(45, 100, 50));
  crown_ = AddTexture(kCrownWidth, kCrownWidth, false, cv::Vec3b(40, 95, 55));
  crown_bottom_ = AddTexture(kCrownWidth, kCrownWidth, false, cv::Vec3b(25, 55, 30));
  bark_ = AddTexture(kTrunkWidth, kCrownBottom, true, cv::Vec3b(45, 65, 90));

  const double s_begin = -o_.margin_before_m, s_end = o_.length_m + o_.margin_after_m;
  const int num_slots =
      std::max(1, static_cast<int>(std::floor((s_end - s_begin) / v_.stretch_length_m)));
  const double slot_m = (s_end - s_begin) / num_slots;
  for (const int side : {-1, 1}) {
    std::vector<double> poles_s;
    for (const Surface& s : world_->surfaces) {
      if (s.kind != SurfaceKind::kPole) continue;
      const Eigen::Vector3d c = 0.25 * (s.corners_in_world[0] + s.corners_in_world[1] +
                                        s.corners_in_world[2] + s.corners_in_world[3]);
      const RoadCoordinates rc = world_->centreline.ToRoad(c.head<2>());
      if (rc.d_m * side > 0) poles_s.push_back(rc.s_m);
    }
    // round(fraction * slots) slots of this side, at random; neighbours merge into one stretch.
    std::vector<int> order(num_slots);
    for (int i = 0; i < num_slots; ++i) order[i] = i;
    for (int i = num_slots - 1; i > 0; --i) std::swap(order[i], order[rng_.UniformInt(0, i)]);
    const int count = static_cast<int>(std::lround(v_.fraction * num_slots));
    std::vector<char> chosen(num_slots, 0);
    for (int i = 0; i < count; ++i) chosen[order[i]] = 1;
    for (int i = 0; i < num_slots;) {
      if (!chosen[i]) {
        ++i;
        continue;
      }
      int j = i;
      while (j < num_slots && chosen[j]) ++j;
      const double s0 = s_begin + i * slot_m, s1 = s_begin + j * slot_m;
      world_->vegetation.push_back({side, s0, s1});
      AddHedge(side, s0, s1);
      AddTrees(side, s0, s1, poles_s);
      i = j;
    }
  }
}

}  // namespace

void VegetationOptions::Check() const {
  EPILOC_CHECK(fraction >= 0 && fraction <= 1,
               "vegetation options: fraction = {} must be in [0, 1]", fraction);
  EPILOC_CHECK(stretch_length_m >= 10 && std::isfinite(stretch_length_m),
               "vegetation options: stretch_length_m = {} must be at least 10 m", stretch_length_m);
  EPILOC_CHECK(tree_spacing_m >= kCrownWidth + 0.5 && std::isfinite(tree_spacing_m),
               "vegetation options: tree_spacing_m = {} must leave 0.5 m between the {} m crowns",
               tree_spacing_m, kCrownWidth);
  EPILOC_CHECK(foliage_period_m >= 0.1 && foliage_period_m <= 2,
               "vegetation options: foliage_period_m = {} must be in [0.1, 2]", foliage_period_m);
}

void AddVegetation(World* world) {
  world->options.vegetation.Check();
  VegetationBuilder(world).Build();
}

Texture VegetationTexture(cv::Size size,
                          int period_px,
                          double metres_per_pixel,
                          bool bark,
                          const cv::Vec3b& base_bgr,
                          uint64_t seed) {
  EPILOC_CHECK(period_px >= 4 && size.width >= 1 && size.height >= 1,
               "vegetation texture: period {} px, size {}x{}", period_px, size.width, size.height);
  Rng rng(seed);
  const int n = period_px;
  // Drawn three periods wide and high, the middle period cut out: shapes crossing its border
  // continue on the opposite side, so the tile repeats seamlessly.
  cv::Mat canvas(3 * n, 3 * n, CV_8UC3, cv::Scalar(base_bgr[0], base_bgr[1], base_bgr[2]));
  const auto shade = [&](double lo, double hi) {
    const double k = rng.Uniform(lo, hi);
    return cv::Scalar(base_bgr[0] * k, base_bgr[1] * k, base_bgr[2] * k);
  };
  if (bark) {
    // Vertical furrows and plates.
    for (int i = 0; i < n / 2; ++i) {
      const int x = rng.UniformInt(0, n - 1), y = rng.UniformInt(0, n - 1);
      const int len = rng.UniformInt(n / 4, n), width = rng.UniformInt(1, 3);
      const cv::Scalar colour = shade(0.45, 1.5);
      for (int dx = 0; dx < 3; ++dx) {
        for (int dy = 0; dy < 3; ++dy) {
          cv::line(canvas, cv::Point(x + dx * n, y + dy * n),
                   cv::Point(x + dx * n, y + dy * n + len), colour, width);
        }
      }
    }
  } else {
    // Leaves: overlapping ellipses of several shades, with dark gaps between them.
    const int leaves = n * n / 6;
    for (int i = 0; i < leaves; ++i) {
      const int x = rng.UniformInt(0, n - 1), y = rng.UniformInt(0, n - 1);
      const cv::Size axes(rng.UniformInt(2, std::max(2, n / 6)), rng.UniformInt(1, 3));
      const double angle = rng.Uniform(0, 180);
      const cv::Scalar colour = rng.Bernoulli(0.15) ? shade(0.3, 0.5) : shade(0.8, 1.8);
      for (int dx = 0; dx < 3; ++dx) {
        for (int dy = 0; dy < 3; ++dy) {
          cv::ellipse(canvas, cv::Point(x + dx * n, y + dy * n), axes, angle, 0, 360, colour,
                      cv::FILLED, cv::LINE_AA);
        }
      }
    }
  }
  const cv::Mat tile = canvas(cv::Rect(n, n, n, n));
  Texture texture;
  texture.metres_per_pixel = metres_per_pixel;
  cv::repeat(tile, (size.height + n - 1) / n, (size.width + n - 1) / n, texture.image);
  texture.image = texture.image(cv::Rect(0, 0, size.width, size.height)).clone();
  return texture;
}

}  // namespace epiloc
