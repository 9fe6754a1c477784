#include "epiloc/cli/commands.h"

#include <string>
#include <vector>

#include "cli_common.h"

namespace epiloc {

const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"synth", "Generate a synthetic street: survey + query drives, LiDAR map, exact truth",
       RunSynth},
      {"import-kitti", "Convert a KITTI raw synced drive into a drive directory", RunImportKitti},
      {"build-db", "Add a survey drive to a route database (SIFT features, positions)", RunBuildDb},
      {"triangulate", "Triangulate a route database's survey features into 3-D points",
       RunTriangulate},
      {"info", "Summarise a route database", RunInfo},
      {"build-map", "Merge a drive's LiDAR scans into a (coloured) point-cloud map", RunBuildMap},
      {"lidar-track",
       "Check a drive's track against its LiDAR scans; write the drive with the LiDAR's path",
       RunLidarTrack},
      {"render", "Render a point-cloud map at a frame's pose", RunRender},
      {"anchor", "Anchor frames in a LiDAR map: 6-DoF pose by rendering, matching and PnP",
       RunAnchor},
      {"vo", "Monocular visual odometry of a drive: relative camera trajectory (TUM)", RunVo},
      {"calibrate-radial",
       "Estimate a residual radial distortion of a drive's camera from a LiDAR map",
       RunCalibrateRadial},
      {"georef", "Georeference a VO/SLAM trajectory with anchors: paper, sim3, piecewise",
       RunGeoref},
      {"localize", "Localize a drive along the route: epipolar distance, DTW, V-fit", RunLocalize},
      {"evaluate", "Compare results with ground truth: tables, JSON, HTML report", RunEvaluate},
      {"export", "Export result trajectories: TUM, KITTI, GeoJSON, KML, GPX", RunExport},
  };
  return commands;
}

std::string SuggestCommand(const std::string& typed) {
  std::vector<std::string> names;
  for (const Command& command : Commands()) names.push_back(command.name);
  return Suggest(typed, names);
}

}  // namespace epiloc
