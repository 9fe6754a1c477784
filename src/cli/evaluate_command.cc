#include <cstdio>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/eval/evaluate.h"
#include "epiloc/eval/report.h"

namespace epiloc {
namespace {

// "A,B,C" as three finite numbers; `flag` names the option in messages.
Eigen::Vector3d ParseTriple(const std::string& text, const std::string& flag) {
  const std::vector<std::string> parts = SplitCsvLine(text);
  const std::string where = flag + " '" + text + "'";
  if (parts.size() != 3) Throw("{}: expected three comma-separated numbers", where);
  return {ParseDouble(parts[0], where), ParseDouble(parts[1], where), ParseDouble(parts[2], where)};
}

}  // namespace

int RunEvaluate(int argc, char** argv) {
  CLI::App app(
      "Compare localizer results (and the drive's GNSS as the 'gps' baseline) with ground truth: "
      "along-track, cross-track, horizontal, vertical and 3-D error per method; tables on stdout, "
      "optional JSON and a self-contained HTML report with plots (gnuplot).",
      "evaluate");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  EvaluateInputs inputs;
  std::string truth_format = "auto", truth_origin, lever_arm, association = "auto";
  std::string report_path, json_path, errors_path;
  bool no_gnss = false, no_png = false;
  ReportOptions report;
  app.add_option("--result", inputs.result_path,
                 "Result CSV (frame,timestamp_s,lat_deg,lon_deg,alt_m,s_m,db_frame,method,status); "
                 "omit to evaluate the GNSS of --gnss alone");
  app.add_option("--truth", inputs.truth_path,
                 "Ground truth: drive directory, KITTI OXTS folder, TUM, KITTI poses, NDT CSV or "
                 "position CSV")
      ->required();
  app.add_option("--truth-format", truth_format,
                 "auto | drive | kitti_oxts | tum | kitti_poses | ndt | csv")
      ->capture_default_str();
  app.add_option(
      "--truth-origin", truth_origin,
      "LAT,LON,ALT of the local frame of tum / kitti_poses / ndt / csv x_m ground truth");
  app.add_option("--truth-yaw-deg", inputs.truth.yaw_deg,
                 "Rotation of that frame about up relative to ENU, degrees counter-clockwise")
      ->capture_default_str();
  app.add_option("--truth-lever-arm", lever_arm,
                 "X,Y,Z camera centre in the IMU/sensor frame (x forward, y left, z up), metres, "
                 "for kitti_oxts and ndt ground truth");
  app.add_option("--truth-times", inputs.truth.times_path,
                 "Timestamps file of kitti_poses ground truth (line i = pose i)");
  app.add_option("--route", inputs.route_db_path, "Measure along this route database's route");
  app.add_option("--route-drive", inputs.route_drive_dir,
                 "Measure along the ground-truth track of this drive (default: the ground truth)");
  app.add_option("--gnss", inputs.gnss_drive_dir,
                 "Add the 'gps' baseline: this drive's GNSS at the evaluated frames' times");
  app.add_flag("--no-gnss", no_gnss,
               "Do not add the gps baseline from a drive-directory ground truth automatically");
  app.add_option("--associate", association,
                 "auto | frame | time: match rows to ground truth by frame number or time")
      ->capture_default_str();
  app.add_option("--max-gap-s", inputs.evaluate.max_gap_s,
                 "Time association: rows further from ground truth are unmatched (counted)")
      ->capture_default_str();
  app.add_option("--projection-window-m", inputs.evaluate.projection_window_m,
                 "Route part (+-) around the truth's s that estimates are projected onto")
      ->capture_default_str();
  app.add_option("--on-route-m", inputs.evaluate.on_route_m,
                 "Frames whose truth is beyond the route's ends or farther than this beside it "
                 "are counted as off the route (not localizing them is right)")
      ->capture_default_str();
  app.add_option("--report", report_path, "Write an HTML report (plots in <name>_files/)");
  app.add_option("--json", json_path, "Write all metrics as JSON");
  app.add_option("--errors", errors_path,
                 "Write each evaluated frame's errors and sigmas per method as CSV");
  app.add_option("--gnuplot", report.gnuplot, "gnuplot executable")->capture_default_str();
  app.add_flag("--no-png", no_png, "Report: SVG plots only, no PNG copies");
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  CheckCommandOutputs({{"--json", json_path}, {"--report", report_path}, {"--errors", errors_path}},
                      {{"--result", inputs.result_path},
                       {"--truth", inputs.truth_path},
                       {"--truth-times", inputs.truth.times_path},
                       {"--route", inputs.route_db_path},
                       {"--route-drive", inputs.route_drive_dir},
                       {"--gnss", inputs.gnss_drive_dir}});

  inputs.truth.format = ParseTruthFormat(truth_format);
  if (!truth_origin.empty()) {
    const Eigen::Vector3d o = ParseTriple(truth_origin, "--truth-origin");
    inputs.truth.origin = Geodetic{o.x(), o.y(), o.z()};
  }
  if (!lever_arm.empty()) inputs.truth.lever_arm_m = ParseTriple(lever_arm, "--truth-lever-arm");
  inputs.evaluate.association = ParseAssociation(association);
  inputs.auto_gnss = !no_gnss;
  report.png = !no_png;
  if (!report_path.empty() && !GnuplotAvailable(report.gnuplot)) {
    Throw(
        "gnuplot not found ('{}' does not run): install gnuplot-nox (apt-get install "
        "gnuplot-nox), or drop --report",
        report.gnuplot);
  }

  const Evaluation eval = EvaluateFiles(inputs);
  std::printf("%s", FormatEvaluationTables(eval).c_str());
  if (!json_path.empty()) {
    WriteEvaluationJson(eval, json_path);
    spdlog::info("wrote {}", json_path);
  }
  if (!errors_path.empty()) {
    WriteFrameErrorsCsv(eval, errors_path);
    spdlog::info("wrote {}", errors_path);
  }
  if (!report_path.empty()) {
    WriteHtmlReport(eval, report_path, report);
    spdlog::info("wrote {}", report_path);
  }
  return kExitOk;
}

}  // namespace epiloc
