#include <algorithm>
#include <filesystem>
#include <set>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/error.h"
#include "epiloc/db/database.h"
#include "epiloc/eval/evaluate.h"

namespace epiloc {
namespace fs = std::filesystem;
namespace {

std::string DriveJson(const std::string& dir) { return (fs::path(dir) / "drive.json").string(); }

// The distinct frames of a result (by frame number, or by time for rows without one), by time.
std::vector<FrameRecord> ResultFrames(const ResultTable& table) {
  std::set<frame_t> frames;
  std::set<double> times;
  std::vector<FrameRecord> records;
  for (const auto& row : table.rows) {
    const bool is_new = row.frame != kInvalidFrame ? frames.insert(row.frame).second
                                                   : times.insert(row.timestamp_s).second;
    if (is_new) records.push_back({row.frame, row.timestamp_s, ""});
  }
  std::stable_sort(records.begin(), records.end(), [](const FrameRecord& a, const FrameRecord& b) {
    return a.timestamp_s < b.timestamp_s;
  });
  return records;
}

bool HasMethod(const ResultTable& table, const std::string& method) {
  return std::any_of(table.rows.begin(), table.rows.end(),
                     [&](const ResultRow& r) { return r.method == method; });
}

}  // namespace

EvaluationRoute RouteFromTrack(const PositionTrack& track) {
  EPILOC_CHECK(!track.samples.empty(), "{}: no positions to make a route of", track.source);
  EvaluationRoute route;
  route.origin = track.samples.front().position;
  route.source = "ground truth " + track.source;
  const EnuFrame enu(route.origin);
  for (const auto& sample : track.samples)
    route.points_in_enu.push_back(enu.ToEnu(sample.position));
  return route;
}

EvaluationRoute RouteFromDrive(const std::string& drive_dir) {
  const Drive drive = LoadDrive(drive_dir);
  if (!drive.ground_truth || drive.ground_truth->samples.empty()) {
    Throw("{}: the drive has no ground truth to make a route of (--route-drive)",
          DriveJson(drive_dir));
  }
  EvaluationRoute route = RouteFromTrack(*drive.ground_truth);
  route.source = "ground truth of drive " + drive_dir;
  return route;
}

EvaluationRoute RouteFromDatabase(const std::string& db_path) {
  if (!fs::exists(db_path)) Throw("{}: no such database (--route)", db_path);
  const Database db(db_path, Database::Mode::kReadOnly);
  const auto origin = db.EnuOrigin();
  EvaluationRoute route;
  route.points_in_enu = db.ReadRoute();
  if (!origin || route.points_in_enu.size() < 2) {
    Throw("{}: the database has no route yet (build-db a survey drive first)", db_path);
  }
  route.origin = *origin;
  route.source = "route database " + db_path;
  return route;
}

void EvaluateInputs::Check() const {
  EPILOC_CHECK(!truth_path.empty(), "no ground truth given (--truth)");
  EPILOC_CHECK(route_db_path.empty() || route_drive_dir.empty(),
               "give --route or --route-drive, not both");
  truth.Check();
  evaluate.Check();
}

Evaluation EvaluateFiles(const EvaluateInputs& inputs) {
  inputs.Check();
  const TruthFormat truth_format = inputs.truth.format == TruthFormat::kAuto
                                       ? DetectTruthFormat(inputs.truth_path)
                                       : inputs.truth.format;
  TruthOptions truth_options = inputs.truth;
  truth_options.format = truth_format;
  const PositionTrack truth = ReadTruth(inputs.truth_path, truth_options);

  ResultTable result;
  if (!inputs.result_path.empty()) result = ReadResultCsv(inputs.result_path);
  std::string gnss_dir = inputs.gnss_drive_dir;
  if (!gnss_dir.empty() && HasMethod(result, "gps")) {
    Throw("{}: the result already has gps rows; drop --gnss {}", inputs.result_path, gnss_dir);
  }
  if (gnss_dir.empty() && inputs.auto_gnss && truth_format == TruthFormat::kDrive &&
      !HasMethod(result, "gps")) {
    gnss_dir = inputs.truth_path;
  }
  if (!gnss_dir.empty()) {
    const Drive drive = LoadDrive(gnss_dir);
    if (drive.gnss.samples.empty()) {
      if (inputs.gnss_drive_dir.empty()) {
        spdlog::info("{}: no GNSS, no gps baseline", DriveJson(gnss_dir));
        gnss_dir.clear();
      } else {
        Throw("{}: the drive has no GNSS positions (--gnss)", DriveJson(gnss_dir));
      }
    }
    if (!gnss_dir.empty()) {
      const auto frames = result.rows.empty() ? drive.frames : ResultFrames(result);
      auto rows = GnssBaselineRows(drive.gnss, frames, drive.max_gap_s);
      for (auto& row : rows) row.extra.resize(result.extra_columns.size());
      result.rows.insert(result.rows.end(), rows.begin(), rows.end());
      if (result.path.empty()) result.path = DriveJson(gnss_dir);
    }
  }
  if (result.rows.empty()) {
    Throw(
        "nothing to evaluate: give --result RESULT.csv, or --gnss DRIVE_DIR to evaluate a "
        "drive's GNSS alone");
  }

  EvaluationRoute route = !inputs.route_db_path.empty() ? RouteFromDatabase(inputs.route_db_path)
                          : !inputs.route_drive_dir.empty() ? RouteFromDrive(inputs.route_drive_dir)
                                                            : RouteFromTrack(truth);
  Evaluation eval = Evaluate(result, truth, route, inputs.evaluate);
  auto& in = eval.inputs;
  in.emplace_back("result", inputs.result_path.empty() ? "(none)" : inputs.result_path);
  in.emplace_back("ground truth", fmt::format("{} ({}, {} samples)", inputs.truth_path,
                                              TruthFormatName(truth_format), truth.samples.size()));
  if (inputs.truth.origin) {
    const Geodetic& o = *inputs.truth.origin;
    in.emplace_back("truth origin", fmt::format("{:.9f}, {:.9f}, {:.3f}; yaw {} deg", o.lat_deg,
                                                o.lon_deg, o.alt_m, inputs.truth.yaw_deg));
  }
  if (inputs.truth.lever_arm_m) {
    const auto& l = *inputs.truth.lever_arm_m;
    in.emplace_back("truth lever arm", fmt::format("{}, {}, {} m", l.x(), l.y(), l.z()));
  }
  in.emplace_back("gps baseline", gnss_dir.empty() ? "(none added)" : "GNSS of drive " + gnss_dir);
  in.emplace_back("route", fmt::format("{} ({:.1f} m, {} points)", eval.route.source,
                                       eval.route_length_m, eval.route.points_in_enu.size()));
  in.emplace_back("ENU origin", fmt::format("{:.9f}, {:.9f}, {:.3f}", route.origin.lat_deg,
                                            route.origin.lon_deg, route.origin.alt_m));
  in.emplace_back("association",
                  eval.association == Association::kFrame
                      ? std::string("by frame number")
                      : fmt::format("by time, max gap {} s", inputs.evaluate.max_gap_s));
  return eval;
}

}  // namespace epiloc
