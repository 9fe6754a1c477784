// Appearance variants of a synthetic data set: what differs between the survey's day and the
// query's besides camera and path. Moving cars (a lead vehicle, traffic), parked cars changed in
// the query's world, and the sun (shading and cast shadows) per drive. (Vegetation belongs to the
// world: WorldOptions::vegetation; exposure and white balance to each drive's RenderOptions.)
// All are off by default, and the frames are then exactly those rendered without them.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/synth/cars.h"
#include "epiloc/synth/lighting.h"
#include "epiloc/synth/moving_objects.h"
#include "epiloc/synth/render.h"
#include "epiloc/synth/trajectory.h"
#include "epiloc/synth/world.h"

namespace epiloc {

struct AppearanceOptions {
  MovingObjectOptions moving;  // lead vehicle (the same car in both drives) and traffic
  // Share of the parking slots whose car is removed, added or replaced in the query's world.
  double query_parked_cars_changed = 0.0;
  std::optional<SunOptions> survey_sun;  // none: unshaded, as without a sun
  std::optional<SunOptions> query_sun;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// What one drive sees: its world and, optionally, the sun and moving cars.
struct DriveScene {
  std::shared_ptr<const World> world;               // the query's may differ by parked cars
  std::shared_ptr<const Lighting> lighting;         // null: unshaded
  std::shared_ptr<const DriveObjects> objects;      // null: no moving cars
  std::vector<ParkedCarChange> parked_car_changes;  // query: slots changed from the survey's world

  // Renders the frame at `timestamp_s` seen from cam_from_world (the path's pose then), with the
  // moving cars at that time and the sun (see Renderer::Render for the other arguments).
  RenderResult Render(const Renderer& renderer,
                      double timestamp_s,
                      const Rigid3d& cam_from_world,
                      const std::optional<Rigid3d>& cam_from_world_exposure_end = std::nullopt,
                      std::optional<uint64_t> noise_seed = std::nullopt) const;
};

// The survey's (index 0) and the query's (1) scenes. `survey_world` is the data set's world,
// `seed` its seed (the lead vehicle's model, the query's parked cars and each drive's traffic
// derive from it).
std::array<DriveScene, 2> MakeDriveScenes(const AppearanceOptions& options,
                                          std::shared_ptr<const World> survey_world,
                                          const DrivePath& survey,
                                          const DrivePath& query,
                                          uint64_t seed);

// Writes what the variants add to a data set directory:
//   appearance.json                    the variants of both drives (sun, exposure, white balance,
//                                      moving cars, parked cars changed, vegetation)
//   survey|query/moving_objects.csv    per frame, every moving car's exact pose (DriveObjects)
//   query/world.json                   the query's world when its parked cars differ (hidden
//                                      surfaces flagged), query/parked_cars_changed.csv the slots
// `render` and `frame_times_s` are per drive (survey, query). Throws Error on I/O failure.
void WriteAppearance(const std::string& out_dir,
                     const AppearanceOptions& options,
                     const VegetationOptions& vegetation,
                     const std::array<RenderOptions, 2>& render,
                     const std::array<DriveScene, 2>& scenes,
                     const std::array<std::vector<double>, 2>& frame_times_s);

}  // namespace epiloc
