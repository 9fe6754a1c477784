#include <cstdio>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "cli_common.h"
#include "epiloc/anchor/anchor.h"
#include "epiloc/anchor/frame_view.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"

namespace epiloc {
namespace {

// "x,y,z,qw,qx,qy,qz": camera centre in the map's ENU frame (metres) and the rotation
// map_from_cam (camera x right, y down, z forward).
Rigid3d ParsePose(const std::string& text) {
  const std::vector<std::string> parts = SplitCsvLine(text);
  const std::string where = "--pose '" + text + "'";
  if (parts.size() != 7) Throw("{}: expected x,y,z,qw,qx,qy,qz", where);
  double v[7];
  for (int i = 0; i < 7; ++i) v[i] = ParseDouble(parts[i], where);
  const Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
  if (q.norm() < 1e-9) Throw("{}: the quaternion is zero", where);
  return Rigid3d(q.normalized(), Eigen::Vector3d(v[0], v[1], v[2]));
}

void WriteImage(const std::string& path, const cv::Mat& image) {
  AtomicFile file(path);
  if (!cv::imwrite(file.temp_path(), image)) Throw("{}: cannot write image", path);
  file.Commit();
}

}  // namespace

int RunRender(int argc, char** argv) {
  CLI::App app(
      "Render a point-cloud map into a frame's undistorted camera at the frame's pose (ground "
      "truth if the drive has it, else the GNSS prior) or at a given pose.",
      "render");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  FrameViewInputs inputs;
  std::string pose_text, prior = "auto", shading = "auto", origin_text, db_path;
  std::string out_path, depth_path, compare_path;
  app.add_option("--cloud", inputs.cloud_path, "Map: point-cloud file or tile directory")
      ->required();
  app.add_option("--drive", inputs.drive_dir, "Drive directory of the frame")->required();
  app.add_option("--frame", inputs.frame, "Frame number")->required();
  app.add_option("--pose", pose_text,
                 "Camera pose x,y,z,qw,qx,qy,qz: centre in the map's ENU frame (metres) and "
                 "rotation map_from_cam");
  app.add_option("--prior", prior, "Pose when --pose is not given: auto | truth | gnss")
      ->capture_default_str();
  app.add_option("--shading", shading, "auto | intensity | colour")->capture_default_str();
  app.add_option("--map-photos", inputs.photos_dir,
                 "Drive of the map's photographs: texture the view from them per pixel");
  app.add_option("--splat-size", inputs.render.splat_size_m, "Metric splat size, metres")
      ->capture_default_str();
  app.add_option("--camera-height", inputs.prior.camera_height_m,
                 "GNSS prior: camera above the map's ground, metres")
      ->capture_default_str();
  app.add_option("--cloud-origin", origin_text,
                 "LAT,LON,ALT of the cloud's ENU origin (when it has no sidecar)");
  app.add_option("--db", db_path, "Route database whose ENU origin the cloud uses (no sidecar)");
  app.add_option("--out", out_path, "Rendered view (PNG)")->required();
  app.add_option("--depth", depth_path, "Depth buffer, 16-bit PNG, metres * 256 (0 = none)");
  app.add_option("--compare", compare_path, "The undistorted frame above the rendering (PNG)");
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  CheckCommandOutputs({{"--out", out_path}, {"--depth", depth_path}, {"--compare", compare_path}},
                      {{"--cloud", inputs.cloud_path},
                       {"--drive", inputs.drive_dir},
                       {"--map-photos", inputs.photos_dir},
                       {"--db", db_path}});
  for (const auto& [option, path] :
       {std::pair<std::string, std::string>{"--out", out_path}, {"--depth", depth_path},
        {"--compare", compare_path}}) {
    if (!path.empty() && !cv::haveImageWriter(path)) {
      Throw("{} {}: not an image format OpenCV writes (use .png)", option, path);
    }
  }

  MapOriginInputs origin_inputs{inputs.cloud_path, std::nullopt, db_path};
  if (!origin_text.empty()) origin_inputs.explicit_origin = ParseGeodetic(origin_text, "--cloud-origin");
  inputs.map_origin = ResolveMapOrigin(origin_inputs).enu_origin;
  if (!pose_text.empty()) inputs.map_from_cam = ParsePose(pose_text);
  inputs.pose = ParseViewPose(prior);
  inputs.render.shading = ParseRenderShading(shading);

  const FrameView view = RenderFrameView(inputs);
  WriteImage(out_path, view.render.image);
  if (!depth_path.empty()) WriteDepthPng(view.render.depth, depth_path);
  if (!compare_path.empty()) {
    WriteImage(compare_path, StackFrameAndRendering(view.frame, view.render.image));
  }
  const Eigen::Vector3d& c = view.map_from_cam.translation;
  const Eigen::Quaterniond& q = view.map_from_cam.rotation;
  std::printf("%s: frame %lld at the %s pose %.3f,%.3f,%.3f,%.6f,%.6f,%.6f,%.6f, %lld points "
              "drawn\n",
              out_path.c_str(), static_cast<long long>(inputs.frame), view.pose_source.c_str(),
              c.x(), c.y(), c.z(), q.w(), q.x(), q.y(), q.z(),
              static_cast<long long>(view.render.points_drawn));
  return kExitOk;
}

}  // namespace epiloc
