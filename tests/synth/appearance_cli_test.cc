// End to end: `epiloc synth` with every appearance variant at once writes frames that are the
// library's renderings of the variants, and its ground truth still projects the world's
// checkerboard markers onto their X-corners in the written frames.
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include <sys/wait.h>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/io/drive.h"
#include "epiloc/synth/drive_gen.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

const char* const kFlags =
    " --length-m 40 --seed 3 --survey-rate-hz 4 --query-rate-hz 4 --no-lidar --clean-query"
    " --lead-vehicle-gap-m 12 --traffic 3 --query-parked-cars-changed 0.4"
    " --survey-sun 120,40 --query-sun 250,25 --query-exposure 1.15"
    " --query-white-balance 1.1,1,0.85 --survey-white-balance 0.95,1,1.05 --vegetation 0.5"
    " --quiet";

// The same options, as the command sets them.
SynthOptions SameOptions() {
  SynthOptions o;
  o.length_m = 40;
  o.seed = 3;
  o.survey.frame_rate_hz = 4;
  o.query.frame_rate_hz = 4;
  o.lidar = false;
  o.query.render = o.survey.render;  // --clean-query
  o.query.exposure_s = 0;
  o.query.wobble_yaw_deg = o.query.wobble_pitch_deg = 0;
  o.appearance.moving.lead_vehicle_gap_m = 12;
  o.appearance.moving.traffic = 3;
  o.appearance.query_parked_cars_changed = 0.4;
  o.appearance.survey_sun = SunOptions();
  o.appearance.survey_sun->azimuth_deg = 120;
  o.appearance.survey_sun->elevation_deg = 40;
  o.appearance.query_sun = SunOptions();
  o.appearance.query_sun->azimuth_deg = 250;
  o.appearance.query_sun->elevation_deg = 25;
  o.query.render.exposure_gain = 1.15;
  o.query.render.white_balance_rgb = {1.1, 1.0, 0.85};
  o.survey.render.white_balance_rgb = {0.95, 1.0, 1.05};
  o.world.vegetation.fraction = 0.5;
  return o;
}

int RunSynthCommand(const std::string& args) {
  const std::string command = std::string(EPILOC_BINARY) + " synth " + args + " >/dev/null 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(SynthCommand, AllAppearanceVariantsKeepTheGroundTruthExact) {
  const fs::path out = fs::temp_directory_path() / "epiloc_synth_appearance_cli";
  fs::remove_all(out);
  ASSERT_EQ(RunSynthCommand("--out " + out.string() + kFlags), 0);
  for (const char* file :
       {"appearance.json", "world.json", "survey/moving_objects.csv", "query/moving_objects.csv",
        "query/world.json", "query/parked_cars_changed.csv"}) {
    EXPECT_TRUE(fs::exists(out / file)) << file;
  }

  const SynthOptions options = SameOptions();
  const auto world = std::make_shared<const World>(BuildWorld(options.ResolvedWorldOptions()));
  EXPECT_FALSE(world->vegetation.empty());
  const EnuFrame world_frame(world->origin());
  const DrivePath survey(*world, options.survey, options.length_m, MixSeed(options.seed, 100));
  const DrivePath query(*world, options.query, options.length_m, MixSeed(options.seed, 101));
  const std::array<DriveScene, 2> scenes =
      MakeDriveScenes(options.appearance, world, survey, query, options.seed);
  ASSERT_NE(scenes[1].world, scenes[0].world);

  int corners = 0, identical = 0, frames = 0;
  double sum = 0, max_error = 0;
  for (int d = 0; d < 2; ++d) {
    const DriveOptions& drive_options = d == 0 ? options.survey : options.query;
    const DrivePath& path = d == 0 ? survey : query;
    const Drive drive = LoadDrive((out / (d == 0 ? "survey" : "query")).string());
    ASSERT_TRUE(drive.ground_truth.has_value());
    RenderOptions with_ids = drive_options.render;
    with_ids.surface_ids = true;
    const Renderer renderer(drive_options.camera, with_ids);
    const Camera& camera = drive_options.camera;
    const World& scene_world = *scenes[d].world;
    for (size_t f = 0; f < drive.frames.size(); ++f) {
      const PositionSample& truth = drive.ground_truth->samples[f];
      ASSERT_EQ(truth.frame, static_cast<frame_t>(f));
      // The stored ground truth, as a pose in the world frame.
      const Eigen::Matrix3d world_from_cam_r =
          LocalEnuFromWorldEnu(world_frame, truth.position).transpose() *
          truth.enu_from_cam->toRotationMatrix();
      const Eigen::Vector3d centre = world_frame.ToEnu(truth.position);
      const Rigid3d cam_from_world =
          Rigid3d::FromMatrix(world_from_cam_r.transpose(), -world_from_cam_r.transpose() * centre);
      const double t = drive.frames[f].timestamp_s;
      const Rigid3d exact = path.CamFromWorld(t);
      EXPECT_LT((exact.Inverse().translation - centre).norm(), 1e-6);
      const cv::Mat image = cv::imread((fs::path(drive.dir) / drive.frames[f].image).string());
      ASSERT_FALSE(image.empty());
      const RenderResult r = scenes[d].Render(renderer, t, exact);
      ++frames;
      identical += cv::norm(r.image, image, cv::NORM_INF) == 0;
      cv::Mat grey;
      cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
      for (const Marker& m : scene_world.markers) {
        const Eigen::Vector3d x = cam_from_world * m.position_in_world;
        if (x.z() < 1.0) continue;
        const Eigen::Vector2d p = camera.Project(x);
        if (p.x() < 12 || p.y() < 12 || p.x() > camera.width - 13 || p.y() > camera.height - 13)
          continue;
        // The corner's squares must hold a search window of 2 px or more (render_test asks for
        // 7 px with poses facing the markers; a drive sees the facades at a grazing angle).
        const Surface& s = scene_world.surfaces[m.surface];
        double reach = 1e9;
        for (const Eigen::Vector3d& dir :
             {s.u_axis, s.v_axis, Eigen::Vector3d(-s.u_axis), Eigen::Vector3d(-s.v_axis)}) {
          reach = std::min(
              reach, (camera.Project(cam_from_world * (m.position_in_world + m.square_m * dir)) - p)
                         .norm());
        }
        if (reach < 4) continue;
        const int win = std::max(2, std::min(6, static_cast<int>(0.7 * reach)));
        bool visible = true;
        for (int dy = -win - 1; dy <= win + 1 && visible; ++dy) {
          for (int dx = -win - 1; dx <= win + 1 && visible; ++dx) {
            visible = r.surface_id.at<int>(static_cast<int>(std::lround(p.y())) + dy,
                                           static_cast<int>(std::lround(p.x())) + dx) == m.surface;
          }
        }
        if (!visible) continue;
        std::vector<cv::Point2f> corner = {cv::Point2f(p.x() + 0.6, p.y() - 0.6)};
        cv::cornerSubPix(
            grey, corner, cv::Size(win, win), cv::Size(-1, -1),
            cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
        const double error = std::hypot(corner[0].x - p.x(), corner[0].y - p.y());
        sum += error;
        max_error = std::max(max_error, error);
        ++corners;
      }
    }
  }
  std::printf(
      "%d frames (%d identical to the library's rendering), %d marker corners: mean %.3f "
      "px, max %.3f px\n",
      frames, identical, corners, corners ? sum / corners : 0.0, max_error);
  EXPECT_EQ(identical, frames);
  EXPECT_GE(corners, 10);
  EXPECT_LT(sum / std::max(corners, 1), 0.3);
  EXPECT_LT(max_error, 0.5);

  // The moving cars' CSV rows are the scenes' exact states.
  CsvReader csv((out / "query" / "moving_objects.csv").string());
  const std::vector<double> times = query.FrameTimes();
  int rows = 0;
  while (csv.Next()) {
    const int frame = static_cast<int>(csv.GetInt("frame"));
    for (const MovingObjectState& s : scenes[1].objects->StatesAt(times[frame])) {
      if (s.object != csv.GetInt("object")) continue;
      EXPECT_EQ(csv.GetDouble("x_m"), s.world_from_body.translation.x());
      ++rows;
    }
  }
  EXPECT_GT(rows, 0);
  fs::remove_all(out);
}

TEST(SynthCommand, BadAppearanceOptionsAreRefused) {
  const std::string out = (fs::temp_directory_path() / "epiloc_synth_appearance_bad").string();
  EXPECT_EQ(RunSynthCommand("--out " + out + " --survey-sun 120"), 2);  // AZ,EL needs two numbers
  EXPECT_EQ(RunSynthCommand("--out " + out + " --query-parked-cars-changed 2"), 2);
  EXPECT_EQ(RunSynthCommand("--out " + out + " --query-sun 120,5 --length-m 30 --no-lidar"), 1);
  EXPECT_EQ(RunSynthCommand("--out " + out + " --lead-vehicle-gap-m 2 --length-m 30 --no-lidar"),
            1);
  fs::remove_all(out);
}

}  // namespace
}  // namespace epiloc
