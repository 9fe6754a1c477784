// Cars beyond the ones parked when the world is built: a car model (a textured box, as the parked
// cars) to place anywhere, and a query world whose parked cars differ from the survey's.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "epiloc/geo/rigid3.h"
#include "epiloc/synth/world.h"

namespace epiloc {

// A car: five textured quads (two sides, front, back, roof) in its body frame: x forward, y left,
// z up, origin on the road under the centre of its footprint.
struct CarModel {
  double length_m = 0.0, width_m = 0.0, height_m = 0.0;
  double clearance_m = 0.03;      // the box's bottom above the road
  std::vector<Surface> surfaces;  // body frame; `texture` indexes `textures`
  std::vector<Texture> textures;  // with mip levels
};

// A random car of the parked cars' sizes, paints and textures (deterministic for the seed).
CarModel MakeCarModel(uint64_t seed);

// Appends the model's surfaces moved by world_from_body, their texture indices shifted by
// `texture_offset` (where the model's textures start in the caller's texture list).
void PlaceCar(const CarModel& car,
              const Rigid3d& world_from_body,
              int texture_offset,
              std::vector<Surface>* out);

// One parking slot whose car changed.
struct ParkedCarChange {
  int slot = -1;       // index into World::parking_slots
  std::string change;  // "removed", "added" or "replaced"
};

// A copy of `world` in which round(fraction * parking slots) slots, chosen at random, change: a
// parked car is removed or replaced (even odds) by another car, an empty slot gets one. Removed
// cars' surfaces stay in place, hidden (texture -1), so every other surface keeps its index; new
// cars are appended. Textures are shared with `world` (cv::Mat). Deterministic for the seed.
World ChangeParkedCars(const World& world,
                       double fraction,
                       uint64_t seed,
                       std::vector<ParkedCarChange>* changes = nullptr);

}  // namespace epiloc
