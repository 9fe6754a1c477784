// Moving cars of one synthetic drive, rendered on top of the static world (RenderExtras):
//  - a lead vehicle driving ahead in the drive's lane: the same car (model and textures) in every
//    drive of a data set, so its features match between survey and query frames, at a gap that
//    varies slowly, and differently in each drive, with the distance driven;
//  - traffic: other cars in each drive, oncoming in the other lane, or ahead in the drive's lane
//    driving away faster than the drive ever goes.
// Every pose is exact and written per frame (WriteCsv).
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "epiloc/geo/rigid3.h"
#include "epiloc/synth/cars.h"
#include "epiloc/synth/trajectory.h"
#include "epiloc/synth/world.h"

namespace epiloc {

struct MovingObjectOptions {
  // Mean along-road distance from the camera to the lead vehicle's back, metres; 0 = none.
  double lead_vehicle_gap_m = 0.0;
  // The gap varies by up to this share of the mean: two sinusoids of the driven distance with
  // wavelengths 180 m and 65 m, phases drawn per drive. With gap <= 40 m and variation <= 0.4 the
  // gap changes by < 0.9 m per metre driven, so the lead car never reverses.
  double lead_gap_variation = 0.25;
  int traffic = 0;  // other moving cars per drive: two thirds oncoming, one third ahead

  // Throws Error naming the first invalid field.
  void Check() const;
};

// Where one moving car is at one time.
struct MovingObjectState {
  int object = -1;          // index in its drive (the lead vehicle, when present, is 0)
  std::string kind;         // "lead", "oncoming" or "ahead"
  Rigid3d world_from_body;  // body: x forward, y left, z up, origin on the road under its centre
  double s_m = 0.0;         // along-road distance of its centre
  double gap_m = NAN;       // lead vehicle: along-road distance from the camera to its back
  double length_m = 0.0, width_m = 0.0, height_m = 0.0;
};

// The moving cars of one drive. Copies what it needs of the world and the path.
class DriveObjects {
 public:
  // `lead`: the lead vehicle's model, used when options.lead_vehicle_gap_m > 0 (pass the same
  // model to every drive). `seed`: this drive's gap variation and traffic.
  DriveObjects(const World& world,
               const DrivePath& path,
               const MovingObjectOptions& options,
               const CarModel& lead,
               uint64_t seed);

  int num_objects() const { return static_cast<int>(objects_.size()); }
  // The cars on the built road (s within the world's margins) at a time.
  std::vector<MovingObjectState> StatesAt(double timestamp_s) const;
  // Their surfaces posed in the world (kind kCar), `texture` indexing textures().
  std::vector<Surface> SurfacesAt(double timestamp_s) const;
  const std::vector<Texture>& textures() const { return textures_; }

  // Writes one row per frame and car on the road: frame, timestamp_s, object, kind, x_m, y_m, z_m
  // (body origin, world ENU), yaw_rad (of the body's x axis, counter-clockwise from east), s_m,
  // gap_m (lead only), length_m, width_m, height_m. Throws Error on I/O failure.
  void WriteCsv(const std::string& path, const std::vector<double>& frame_times_s) const;

 private:
  struct Object {
    std::string kind;
    int model = 0;
    double lateral_m = 0.0;                  // offset from the centreline, positive left
    double speed_mps = 0.0;                  // ds/dt (negative: oncoming)
    double ref_time_s = 0.0, ref_s_m = 0.0;  // s = ref_s + speed * (t - ref_time)
  };
  double LeadGapAtS(double camera_s_m) const;

  Centreline centreline_;
  DrivePath path_;
  MovingObjectOptions options_;
  double s_begin_m_ = 0.0, s_end_m_ = 0.0;  // the built road
  double road_height_m_ = 0.0;
  double phase_[2] = {0.0, 0.0};
  std::vector<CarModel> models_;  // surfaces only; their textures start at texture_offset_
  std::vector<int> texture_offset_;
  std::vector<Object> objects_;
  std::vector<Texture> textures_;
};

}  // namespace epiloc
