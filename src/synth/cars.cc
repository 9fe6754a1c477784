#include "epiloc/synth/cars.h"

#include <algorithm>
#include <cmath>

#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"
#include "epiloc/synth/texture.h"

namespace epiloc {
namespace {

constexpr double kCarPixelsPerM = 60.0;  // as the parked cars (world.cc)

// A vertical rectangle facing `outward`, as the world builder's uprights: u to the right and v
// downwards for a viewer it faces.
Surface Upright(const Eigen::Vector3d& centre_top,
                const Eigen::Vector3d& outward,
                double width,
                double height,
                int texture) {
  const Eigen::Vector3d right = (-outward).cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d origin = centre_top - 0.5 * width * right;
  Surface s;
  s.kind = SurfaceKind::kCar;
  s.corners_in_world = {origin, origin + width * right, origin + width * right + height * down,
                        origin + height * down};
  s.texture = texture;
  s.texture_origin_in_world = origin;
  s.u_axis = right;
  s.v_axis = down;
  return s;
}

}  // namespace

CarModel MakeCarModel(uint64_t seed) {
  Rng rng(seed);
  CarModel car;
  car.length_m = rng.Uniform(3.9, 4.8);
  car.width_m = rng.Uniform(1.7, 1.9);
  car.height_m = rng.Uniform(1.4, 1.6);
  const cv::Vec3b paint = CarPaint(rng);
  const double l = car.length_m, w = car.width_m, h = car.height_m, top = car.clearance_m + h;
  const auto texture = [&](int face, double width, double height) {
    car.textures.push_back(CarTexture(face, width, height, kCarPixelsPerM, paint, rng.Next()));
    car.textures.back().BuildPyramid();
    return static_cast<int>(car.textures.size()) - 1;
  };
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  car.surfaces.push_back(Upright(Eigen::Vector3d(0, 0.5 * w, top), y, l, h, texture(0, l, h)));
  car.surfaces.push_back(Upright(Eigen::Vector3d(0, -0.5 * w, top), -y, l, h, texture(0, l, h)));
  car.surfaces.push_back(Upright(Eigen::Vector3d(0.5 * l, 0, top), x, w, h, texture(1, w, h)));
  car.surfaces.push_back(Upright(Eigen::Vector3d(-0.5 * l, 0, top), -x, w, h, texture(2, w, h)));
  Surface roof;
  roof.kind = SurfaceKind::kCar;
  const Eigen::Vector3d origin(-0.5 * l, -0.5 * w, top);
  roof.corners_in_world = {origin, origin + l * x, origin + l * x + w * y, origin + w * y};
  roof.texture = texture(3, l, w);
  roof.texture_origin_in_world = origin;
  roof.u_axis = x;
  roof.v_axis = y;
  car.surfaces.push_back(roof);
  return car;
}

void PlaceCar(const CarModel& car,
              const Rigid3d& world_from_body,
              int texture_offset,
              std::vector<Surface>* out) {
  const Eigen::Matrix3d r = world_from_body.rotation.toRotationMatrix();
  for (const Surface& s : car.surfaces) {
    Surface placed = s;
    for (Eigen::Vector3d& c : placed.corners_in_world) c = r * c + world_from_body.translation;
    placed.texture_origin_in_world = r * s.texture_origin_in_world + world_from_body.translation;
    placed.u_axis = r * s.u_axis;
    placed.v_axis = r * s.v_axis;
    placed.texture = s.texture + texture_offset;
    out->push_back(placed);
  }
}

World ChangeParkedCars(const World& world,
                       double fraction,
                       uint64_t seed,
                       std::vector<ParkedCarChange>* changes) {
  EPILOC_CHECK(fraction >= 0 && fraction <= 1,
               "parked cars: the changed fraction {} must be in [0, 1]", fraction);
  World out = world;
  const int num_slots = static_cast<int>(world.parking_slots.size());
  Rng rng(seed);
  std::vector<int> order(num_slots);
  for (int i = 0; i < num_slots; ++i) order[i] = i;
  for (int i = num_slots - 1; i > 0; --i) std::swap(order[i], order[rng.UniformInt(0, i)]);
  std::vector<int> chosen(order.begin(),
                          order.begin() + static_cast<int>(std::lround(fraction * num_slots)));
  std::sort(chosen.begin(), chosen.end());
  const RoadProfile& road = world.options.road;
  for (const int index : chosen) {
    ParkingSlot& slot = out.parking_slots[index];
    std::string change = "added";
    if (slot.first_surface >= 0) {
      for (int k = 0; k < 5; ++k) out.surfaces[slot.first_surface + k].texture = -1;
      change = rng.Bernoulli(0.5) ? "replaced" : "removed";
      slot.first_surface = -1;
    }
    if (change != "removed") {
      // Placed as the world builder parks its cars: jittered along and across the strip, a
      // little askew, facing the traffic of its side.
      const CarModel car = MakeCarModel(MixSeed(seed, 1000 + index));
      const double s = slot.s_m + rng.Uniform(-0.5, 0.5);
      const double d =
          slot.side * (road.lane_width_m + 0.5 * road.parking_width_m) + rng.Uniform(-0.15, 0.15);
      const double yaw =
          world.centreline.YawAt(s) + rng.Uniform(-2, 2) * kDegToRad + (slot.side > 0 ? M_PI : 0.0);
      const Eigen::Vector2d c = world.centreline.PointAt(s, d);
      const Rigid3d world_from_body(
          Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
          Eigen::Vector3d(c.x(), c.y(), world.RoadHeight()));
      slot.first_surface = static_cast<int>(out.surfaces.size());
      PlaceCar(car, world_from_body, static_cast<int>(out.textures.size()), &out.surfaces);
      out.textures.insert(out.textures.end(), car.textures.begin(), car.textures.end());
    }
    if (changes) changes->push_back({index, change});
  }
  return out;
}

}  // namespace epiloc
