// A small synthetic street with its route database, generated once and shared by the test
// processes of the localize and cli tests.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "epiloc/survey/build_db.h"
#include "synth_world_util.h"

namespace epiloc {

// 50 m of street, a clean query at 5 Hz (no noise, blur, gain change or wobble), no LiDAR.
inline SynthOptions SmallStreetOptions() {
  SynthOptions synth;
  synth.length_m = 50;
  synth.seed = 5;
  synth.lidar = false;
  synth.query.render = synth.survey.render;
  synth.query.exposure_s = 0.0;
  synth.query.wobble_yaw_deg = synth.query.wobble_pitch_deg = 0.0;
  synth.query.frame_rate_hz = 5.0;
  return synth;
}

// SharedWorld(name, options) plus `route.sqlite` built from its survey (triangulated), built
// into a private file and renamed so that concurrent test processes never see a partial one.
inline std::string SharedRoute(const std::string& name, const SynthOptions& options) {
  namespace fs = std::filesystem;
  const fs::path dir = SharedWorld(name, options);
  const fs::path db = dir / "route.sqlite";
  if (fs::exists(dir / "route_complete")) return dir.string();
  const fs::path tmp = dir / ("route.sqlite.tmp." + std::to_string(::getpid()));
  fs::remove(tmp);
  BuildDatabase((dir / "survey").string(), tmp.string(), BuildDbOptions());
  fs::rename(tmp, db);
  { std::ofstream(dir / "route_complete") << "ok\n"; }
  return dir.string();
}

}  // namespace epiloc
