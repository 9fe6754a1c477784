#include <cstdio>
#include <string>
#include <vector>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/eval/export.h"

namespace epiloc {

int RunExport(int argc, char** argv) {
  CLI::App app(
      "Export result trajectories (status ok rows) for evo and GIS tools: TUM or KITTI poses in "
      "ENU metres about an origin, GeoJSON, KML or GPX.",
      "export");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string result_path, format, origin, out_path;
  ExportOptions options;
  app.add_option("--result", result_path, "Result CSV")->required();
  app.add_option("--format", format, "tum | kitti | geojson | kml | gpx")->required();
  app.add_option("--method", options.method,
                 "Export only this method (tum/kitti: required if the file has several)");
  app.add_option("--out", out_path, "File to write")->required();
  app.add_option("--origin", origin,
                 "LAT,LON,ALT of the tum/kitti ENU frame (default: the first exported row)");
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  CheckCommandOutputs({{"--out", out_path}}, {{"--result", result_path}});

  options.format = ParseTrajectoryFormat(format);
  if (!origin.empty()) {
    const std::vector<std::string> parts = SplitCsvLine(origin);
    const std::string where = "--origin '" + origin + "'";
    if (parts.size() != 3) Throw("{}: expected LAT,LON,ALT", where);
    options.origin = Geodetic{ParseDouble(parts[0], where), ParseDouble(parts[1], where),
                              ParseDouble(parts[2], where)};
  }
  const ResultTable table = ReadResultCsv(result_path);
  const ExportSummary summary = ExportTrajectory(table, options, out_path);
  std::printf("%s: %lld positions of %s as %s%s\n", out_path.c_str(),
              static_cast<long long>(summary.rows),
              fmt::format("{}", fmt::join(summary.methods, ", ")).c_str(),
              TrajectoryFormatName(options.format).c_str(),
              summary.times_path.empty() ? "" : (", times in " + summary.times_path).c_str());
  return kExitOk;
}

}  // namespace epiloc
