#include "epiloc/synth/moving_objects.h"

#include <algorithm>
#include <cmath>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Wavelengths of the lead gap's variation over the driven distance, and their weights: a real
// follower's gap drifts over tens to hundreds of metres.
constexpr double kGapWavelength1M = 180.0, kGapWavelength2M = 65.0;
constexpr double kGapWeight1 = 2.0 / 3.0, kGapWeight2 = 1.0 / 3.0;

}  // namespace

void MovingObjectOptions::Check() const {
  EPILOC_CHECK(lead_vehicle_gap_m == 0 || (lead_vehicle_gap_m >= 4 && lead_vehicle_gap_m <= 40),
               "moving objects: lead_vehicle_gap_m = {} must be 0 (none) or in [4, 40] m",
               lead_vehicle_gap_m);
  EPILOC_CHECK(lead_gap_variation >= 0 && lead_gap_variation <= 0.4,
               "moving objects: lead_gap_variation = {} must be in [0, 0.4]", lead_gap_variation);
  EPILOC_CHECK(traffic >= 0 && traffic <= 100, "moving objects: traffic = {} must be in [0, 100]",
               traffic);
}

DriveObjects::DriveObjects(const World& world,
                           const DrivePath& path,
                           const MovingObjectOptions& options,
                           const CarModel& lead,
                           uint64_t seed)
    : centreline_(world.centreline),
      path_(path),
      options_(options),
      s_begin_m_(-world.options.margin_before_m),
      s_end_m_(world.options.length_m + world.options.margin_after_m),
      road_height_m_(world.RoadHeight()) {
  options.Check();
  Rng rng(MixSeed(seed, 1));
  for (double& p : phase_) p = rng.Uniform(0, 2 * M_PI);
  const auto add_model = [&](const CarModel& car) {
    texture_offset_.push_back(static_cast<int>(textures_.size()));
    textures_.insert(textures_.end(), car.textures.begin(), car.textures.end());
    CarModel shape = car;
    shape.textures.clear();
    models_.push_back(shape);
    return static_cast<int>(models_.size()) - 1;
  };
  if (options.lead_vehicle_gap_m > 0) {
    Object o;
    o.kind = "lead";
    o.model = add_model(lead);
    o.lateral_m = world.RightLaneCentre();
    objects_.push_back(o);
  }
  if (options.traffic == 0) return;
  // The drive's top speed, from its motion between frames 0.05 s apart.
  const double t0 = path.start_time_s(), t1 = path.end_time_s();
  double top_speed = 0.0;
  for (double t = t0; t < t1; t += 0.05) {
    top_speed = std::max(top_speed, (path.SAt(t + 0.05) - path.SAt(t)) / 0.05);
  }
  const int ahead = options.traffic / 3, oncoming = options.traffic - ahead;
  const double lane = world.options.road.lane_width_m;
  // Oncoming cars share one speed and pass the camera at times at least half a spacing apart, so
  // they stay >= 8 m apart (a car's length plus 3 m) and never overlap.
  const double oncoming_speed = rng.Uniform(7.0, 11.0);
  const double spacing = std::max((t1 - t0) / oncoming, 16.0 / oncoming_speed);
  for (int i = 0; i < oncoming; ++i) {
    Object o;
    o.kind = "oncoming";
    o.model = add_model(MakeCarModel(MixSeed(seed, 100 + i)));
    o.lateral_m = 0.5 * lane + rng.Uniform(-0.25, 0.25);
    o.speed_mps = -oncoming_speed;
    o.ref_time_s = t0 + (i + 0.5 + rng.Uniform(-0.25, 0.25)) * spacing;
    o.ref_s_m = path.SAt(o.ref_time_s);  // it passes the camera then
    objects_.push_back(o);
  }
  // Cars ahead start beyond the lead vehicle's farthest reach and drive away faster than the
  // drive's top speed, so they never meet the drive or the lead vehicle (whose speed is at most
  // 1.9 times the drive's, see lead_gap_variation; 15 m apart among themselves).
  const double lead_reach =
      options.lead_vehicle_gap_m > 0
          ? options.lead_vehicle_gap_m * (1 + options.lead_gap_variation) + lead.length_m
          : 0.0;
  const double ahead_speed = 2.0 * top_speed + rng.Uniform(1.0, 3.0);
  for (int i = 0; i < ahead; ++i) {
    Object o;
    o.kind = "ahead";
    o.model = add_model(MakeCarModel(MixSeed(seed, 200 + i)));
    o.lateral_m = world.RightLaneCentre() + rng.Uniform(-0.2, 0.2);
    o.speed_mps = ahead_speed;
    o.ref_time_s = t0;
    o.ref_s_m = path.SAt(t0) + lead_reach + 10.0 + 15.0 * i;
    objects_.push_back(o);
  }
}

double DriveObjects::LeadGapAtS(double camera_s_m) const {
  const double a = options_.lead_gap_variation;
  return options_.lead_vehicle_gap_m *
         (1.0 + a * (kGapWeight1 * std::sin(2 * M_PI * camera_s_m / kGapWavelength1M + phase_[0]) +
                     kGapWeight2 * std::sin(2 * M_PI * camera_s_m / kGapWavelength2M + phase_[1])));
}

std::vector<MovingObjectState> DriveObjects::StatesAt(double timestamp_s) const {
  std::vector<MovingObjectState> states;
  for (int i = 0; i < num_objects(); ++i) {
    const Object& o = objects_[i];
    const CarModel& car = models_[o.model];
    MovingObjectState state;
    state.object = i;
    state.kind = o.kind;
    state.length_m = car.length_m;
    state.width_m = car.width_m;
    state.height_m = car.height_m;
    double yaw_offset = 0.0;
    if (o.kind == "lead") {
      const double camera_s = path_.SAt(timestamp_s);
      state.gap_m = LeadGapAtS(camera_s);
      state.s_m = camera_s + state.gap_m + 0.5 * car.length_m;
    } else {
      state.s_m = o.ref_s_m + o.speed_mps * (timestamp_s - o.ref_time_s);
      if (o.speed_mps < 0) yaw_offset = M_PI;
    }
    if (state.s_m < s_begin_m_ || state.s_m > s_end_m_) continue;
    const Eigen::Vector2d c = centreline_.PointAt(state.s_m, o.lateral_m);
    state.world_from_body =
        Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(centreline_.YawAt(state.s_m) + yaw_offset,
                                                     Eigen::Vector3d::UnitZ())),
                Eigen::Vector3d(c.x(), c.y(), road_height_m_));
    states.push_back(state);
  }
  return states;
}

std::vector<Surface> DriveObjects::SurfacesAt(double timestamp_s) const {
  std::vector<Surface> surfaces;
  for (const MovingObjectState& state : StatesAt(timestamp_s)) {
    const int model = objects_[state.object].model;
    PlaceCar(models_[model], state.world_from_body, texture_offset_[model], &surfaces);
  }
  return surfaces;
}

void DriveObjects::WriteCsv(const std::string& path,
                            const std::vector<double>& frame_times_s) const {
  CsvWriter csv(path, {"frame", "timestamp_s", "object", "kind", "x_m", "y_m", "z_m", "yaw_rad",
                       "s_m", "gap_m", "length_m", "width_m", "height_m"});
  for (size_t f = 0; f < frame_times_s.size(); ++f) {
    for (const MovingObjectState& s : StatesAt(frame_times_s[f])) {
      const Eigen::Vector3d x = s.world_from_body.translation;
      const Eigen::Vector3d forward = s.world_from_body.rotation * Eigen::Vector3d::UnitX();
      csv.WriteRow({std::to_string(f), FormatDouble(frame_times_s[f]), std::to_string(s.object),
                    s.kind, FormatDouble(x.x()), FormatDouble(x.y()), FormatDouble(x.z()),
                    FormatDouble(std::atan2(forward.y(), forward.x())), FormatDouble(s.s_m),
                    FormatDouble(s.gap_m), FormatDouble(s.length_m), FormatDouble(s.width_m),
                    FormatDouble(s.height_m)});
    }
  }
  csv.Close();
}

}  // namespace epiloc
