#include "epiloc/cli/commands.h"

#include <algorithm>
#include <numeric>

namespace epiloc {
namespace {

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  std::iota(row.begin(), row.end(), 0);
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

}  // namespace

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
      {"render", "Render a point-cloud map at a frame's pose", RunRender},
      {"anchor", "Anchor frames in a LiDAR map: 6-DoF pose by rendering, matching and PnP",
       RunAnchor},
      {"vo", "Monocular visual odometry of a drive: relative camera trajectory (TUM)", RunVo},
      {"georef", "Georeference a VO/SLAM trajectory with anchors: paper, sim3, piecewise",
       RunGeoref},
      {"localize", "Localize a drive along the route: epipolar distance, DTW, V-fit", RunLocalize},
      {"evaluate", "Compare results with ground truth: tables, JSON, HTML report", RunEvaluate},
      {"export", "Export result trajectories: TUM, KITTI, GeoJSON, KML, GPX", RunExport},
  };
  return commands;
}

std::string SuggestCommand(const std::string& typed) {
  std::string best;
  size_t best_distance = 3;  // more edits than this is no suggestion
  for (const Command& command : Commands()) {
    const size_t distance = EditDistance(typed, command.name);
    if (distance < best_distance ||
        (command.name.rfind(typed, 0) == 0 && !typed.empty() && best.empty())) {
      best_distance = std::min(distance, best_distance);
      best = command.name;
    }
  }
  return best;
}

}  // namespace epiloc
