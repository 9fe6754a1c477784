// `epiloc synth`'s LiDAR flags shape the map: one scan (--lidar-spacing beyond the route) with
// --lidar-rings beams and no range noise puts every point on one of that many elevations seen
// from the scan's pose; --lidar-fov 360 keeps points behind the sensor, the default 180 none.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include <sys/wait.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "epiloc/core/csv.h"
#include "epiloc/synth/lidar.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

int RunSynthCommand(const std::string& args) {
  const std::string command = std::string(EPILOC_BINARY) + " synth " + args + " >/dev/null 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

struct ScanView {
  int scans = 0;
  std::vector<double> elevations_deg;  // of the points, from the first scan's pose
  int behind = 0;                      // points more than 100 deg off the sensor's forward axis
};

ScanView ViewFromFirstScan(const fs::path& out) {
  ScanView view;
  CsvReader scans((out / "lidar" / "scans.csv").string());
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Quaterniond world_from_sensor = Eigen::Quaterniond::Identity();
  while (scans.Next()) {
    if (view.scans++ > 0) continue;
    const auto d = [&](const char* c) { return scans.GetDouble(c); };
    origin = Eigen::Vector3d(d("x_m"), d("y_m"), d("z_m"));
    world_from_sensor = Eigen::Quaterniond(d("qw"), d("qx"), d("qy"), d("qz"));
  }
  for (const LidarPoint& p : ReadPly((out / "lidar" / "map.ply").string())) {
    const Eigen::Vector3d s = world_from_sensor.conjugate() * (p.position.cast<double>() - origin);
    view.elevations_deg.push_back(std::atan2(s.z(), s.head<2>().norm()) * 180.0 / M_PI);
    if (std::abs(std::atan2(s.y(), s.x())) > 100.0 * M_PI / 180.0) ++view.behind;
  }
  return view;
}

TEST(SynthCommand, LidarFlagsShapeTheMap) {
  const fs::path out = fs::temp_directory_path() / "epiloc_synth_lidar_cli";
  const std::string common = " --length-m 30 --seed 5 --query-rate-hz 1 --query-only --quiet";
  fs::remove_all(out);
  ASSERT_EQ(RunSynthCommand("--out " + out.string() + common +
                            " --lidar-spacing 1000 --lidar-rings 16 --lidar-fov 360 "
                            "--lidar-noise 0"),
            0);
  ScanView view = ViewFromFirstScan(out);
  EXPECT_EQ(view.scans, 1);
  ASSERT_GT(view.elevations_deg.size(), 1000u);
  // 16 beams from -25 to +3 deg (LidarOptions): each point within float rounding of one.
  const LidarOptions defaults;
  const double ring_step = (defaults.max_elevation_deg - defaults.min_elevation_deg) / 15.0;
  std::vector<int> per_ring(16, 0);
  for (const double e : view.elevations_deg) {
    const double ring = (e - defaults.min_elevation_deg) / ring_step;
    const long nearest = std::lround(ring);
    ASSERT_GE(nearest, 0);
    ASSERT_LE(nearest, 15);
    EXPECT_NEAR(ring * ring_step, nearest * ring_step, 0.01) << e;
    ++per_ring[nearest];
  }
  EXPECT_GT(std::count_if(per_ring.begin(), per_ring.end(), [](int n) { return n > 0; }), 10);
  EXPECT_GT(view.behind, 100);

  // The defaults: scans every 10 m, forward half only.
  fs::remove_all(out);
  ASSERT_EQ(RunSynthCommand("--out " + out.string() + common), 0);
  view = ViewFromFirstScan(out);
  EXPECT_GE(view.scans, 3);
  EXPECT_EQ(view.behind, 0);

  // Bad values fail with a message, not a map.
  fs::remove_all(out);
  for (const char* bad : {" --lidar-rings 0", " --lidar-spacing -1", " --lidar-fov 400",
                          " --lidar-noise -0.1"}) {
    EXPECT_NE(RunSynthCommand("--out " + out.string() + common + bad), 0) << bad;
  }
  fs::remove_all(out);
}

}  // namespace
}  // namespace epiloc
