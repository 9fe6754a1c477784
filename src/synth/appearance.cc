#include "epiloc/synth/appearance.h"

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

Json SunJson(const std::optional<SunOptions>& sun) {
  if (!sun) return nullptr;
  return {{"azimuth_deg", sun->azimuth_deg},
          {"elevation_deg", sun->elevation_deg},
          {"ambient", sun->ambient},
          {"direct", sun->direct}};
}

}  // namespace

void AppearanceOptions::Check() const {
  moving.Check();
  EPILOC_CHECK(query_parked_cars_changed >= 0 && query_parked_cars_changed <= 1,
               "appearance options: query_parked_cars_changed = {} must be in [0, 1]",
               query_parked_cars_changed);
  if (survey_sun) survey_sun->Check();
  if (query_sun) query_sun->Check();
}

RenderResult DriveScene::Render(const Renderer& renderer,
                                double timestamp_s,
                                const Rigid3d& cam_from_world,
                                const std::optional<Rigid3d>& cam_from_world_exposure_end,
                                std::optional<uint64_t> noise_seed) const {
  RenderExtras extras;
  extras.lighting = lighting.get();
  std::vector<Surface> moving;
  if (objects) {
    moving = objects->SurfacesAt(timestamp_s);
    extras.surfaces = &moving;
    extras.textures = &objects->textures();
  }
  return renderer.Render(*world, cam_from_world, cam_from_world_exposure_end, noise_seed, extras);
}

std::array<DriveScene, 2> MakeDriveScenes(const AppearanceOptions& options,
                                          std::shared_ptr<const World> survey_world,
                                          const DrivePath& survey,
                                          const DrivePath& query,
                                          uint64_t seed) {
  options.Check();
  std::array<DriveScene, 2> scenes;
  scenes[0].world = survey_world;
  scenes[1].world = survey_world;
  if (options.query_parked_cars_changed > 0) {
    scenes[1].world = std::make_shared<const World>(
        ChangeParkedCars(*survey_world, options.query_parked_cars_changed, MixSeed(seed, 302),
                         &scenes[1].parked_car_changes));
  }
  const MovingObjectOptions& moving = options.moving;
  const bool any_moving = moving.lead_vehicle_gap_m > 0 || moving.traffic > 0;
  // The same lead car in both drives.
  const CarModel lead = any_moving ? MakeCarModel(MixSeed(seed, 300)) : CarModel();
  for (int d = 0; d < 2; ++d) {
    DriveScene& scene = scenes[d];
    const std::optional<SunOptions>& sun = d == 0 ? options.survey_sun : options.query_sun;
    if (sun) scene.lighting = std::make_shared<const Lighting>(*scene.world, *sun);
    if (any_moving) {
      scene.objects = std::make_shared<const DriveObjects>(*scene.world, d == 0 ? survey : query,
                                                           moving, lead, MixSeed(seed, 310 + d));
    }
  }
  return scenes;
}

void WriteAppearance(const std::string& out_dir,
                     const AppearanceOptions& options,
                     const VegetationOptions& vegetation,
                     const std::array<RenderOptions, 2>& render,
                     const std::array<DriveScene, 2>& scenes,
                     const std::array<std::vector<double>, 2>& frame_times_s) {
  const fs::path out(out_dir);
  const char* names[2] = {"survey", "query"};
  Json j;
  j["sun_model"] =
      "factor = ambient + direct * max(0, n . sun) * lit; sun azimuth clockwise from north; no "
      "sun: unshaded";
  for (int d = 0; d < 2; ++d) {
    const std::array<double, 3>& wb = render[d].white_balance_rgb;
    j[names[d]] = {
        {"sun", SunJson(d == 0 ? options.survey_sun : options.query_sun)},
        {"exposure_gain", render[d].exposure_gain},
        {"white_balance_rgb", {wb[0], wb[1], wb[2]}},
        {"moving_objects", scenes[d].objects ? scenes[d].objects->num_objects() : 0},
    };
  }
  j["lead_vehicle_gap_m"] = options.moving.lead_vehicle_gap_m;
  j["lead_gap_variation"] = options.moving.lead_gap_variation;
  j["traffic"] = options.moving.traffic;
  j["query_parked_cars_changed"] = options.query_parked_cars_changed;
  j["query_parked_cars_changed_slots"] = scenes[1].parked_car_changes.size();
  j["vegetation"] = {{"fraction", vegetation.fraction},
                     {"stretch_length_m", vegetation.stretch_length_m},
                     {"tree_spacing_m", vegetation.tree_spacing_m},
                     {"foliage_period_m", vegetation.foliage_period_m}};
  const std::string path = (out / "appearance.json").string();
  std::ofstream file(path);
  if (!file) Throw("{}: cannot open for writing", path);
  file << j.dump(1) << '\n';
  file.close();
  if (!file) Throw("{}: write failed", path);

  for (int d = 0; d < 2; ++d) {
    // A drive not written (the survey of `synth --query-only`) gets no moving-object list.
    if (scenes[d].objects && fs::is_directory(out / names[d])) {
      scenes[d].objects->WriteCsv((out / names[d] / "moving_objects.csv").string(),
                                  frame_times_s[d]);
    }
  }
  if (scenes[1].world != scenes[0].world) {
    WriteWorldJson(*scenes[1].world, (out / "query" / "world.json").string());
    CsvWriter csv((out / "query" / "parked_cars_changed.csv").string(),
                  {"slot", "side", "s_m", "change", "first_surface"});
    for (const ParkedCarChange& c : scenes[1].parked_car_changes) {
      const ParkingSlot& slot = scenes[1].world->parking_slots[c.slot];
      csv.WriteRow({std::to_string(c.slot), std::to_string(slot.side), FormatDouble(slot.s_m),
                    c.change, std::to_string(slot.first_surface)});
    }
    csv.Close();
  }
}

}  // namespace epiloc
