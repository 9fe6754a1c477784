#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
#include "epiloc/eval/report.h"
#include "report_internal.h"

namespace epiloc {
namespace {

std::string Metres(double value) {
  if (std::isnan(value)) return "-";
  return fmt::format("{:.3f}", std::abs(value) < 5e-4 ? 0.0 : value);  // no "-0.000"
}
std::string Percent(double share) {
  return std::isnan(share) ? "-" : fmt::format("{:.1f}", 100.0 * share);
}

std::string FormatTable(const std::string& title,
                        const std::vector<TableRow>& rows,
                        const Evaluation& eval) {
  size_t label_width = 12;
  for (const auto& row : rows) label_width = std::max(label_width, row.label.size() + 2);
  std::vector<size_t> widths;
  for (const auto& m : eval.methods) widths.push_back(std::max<size_t>(10, m.method.size() + 2));
  std::string out = title + "\n";
  out += fmt::format("{:<{}}", "", label_width);
  for (size_t j = 0; j < eval.methods.size(); ++j) {
    out += fmt::format("{:>{}}", eval.methods[j].method, widths[j]);
  }
  out += "\n";
  for (const auto& row : rows) {
    if (row.cells.empty()) {  // a section heading
      out += row.label + "\n";
      continue;
    }
    out += fmt::format("{:<{}}", row.label, label_width);
    for (size_t j = 0; j < row.cells.size(); ++j)
      out += fmt::format("{:>{}}", row.cells[j], widths[j]);
    out += "\n";
  }
  return out;
}

nlohmann::json StatisticsJson(const ErrorStatistics& s) {
  nlohmann::json shares = nlohmann::json::object();
  for (size_t i = 0; i < ErrorThresholds().size(); ++i) {
    shares[fmt::format("{}", ErrorThresholds()[i])] = s.share_within[i];
  }
  return {{"count", s.count},           {"min", s.min},   {"max", s.max},
          {"mean_abs", s.mean_abs},     {"bias", s.bias}, {"std", s.std},
          {"median_abs", s.median_abs}, {"rmse", s.rmse}, {"p95_abs", s.p95_abs},
          {"share_within", shares}};
}

}  // namespace

void CreateParentDirectory(const std::string& path) {
  const auto parent = std::filesystem::path(path).parent_path();
  if (parent.empty()) return;
  std::error_code error;
  std::filesystem::create_directories(parent, error);
  if (error) Throw("{}: cannot create the folder {}: {}", path, parent.string(), error.message());
}

std::vector<TableRow> AlongTrackRows(const Evaluation& eval) {
  using Get = std::function<double(const ErrorStatistics&)>;
  const std::vector<std::pair<std::string, Get>> metres = {
      {"Min", [](const ErrorStatistics& s) { return s.min; }},
      {"Max", [](const ErrorStatistics& s) { return s.max; }},
      {"Mean|e|", [](const ErrorStatistics& s) { return s.mean_abs; }},
      {"Bias", [](const ErrorStatistics& s) { return s.bias; }},
      {"Std", [](const ErrorStatistics& s) { return s.std; }},
      {"Median|e|", [](const ErrorStatistics& s) { return s.median_abs; }},
      {"RMSE", [](const ErrorStatistics& s) { return s.rmse; }},
      {"P95|e|", [](const ErrorStatistics& s) { return s.p95_abs; }},
  };
  std::vector<TableRow> rows;
  for (const auto& [label, get] : metres) {
    TableRow row{label, {}};
    for (const auto& m : eval.methods) row.cells.push_back(Metres(get(m.along_track)));
    rows.push_back(row);
  }
  for (size_t i = 0; i < ErrorThresholds().size(); ++i) {
    TableRow row{fmt::format("<={}m [%]", ErrorThresholds()[i]), {}};
    for (const auto& m : eval.methods) row.cells.push_back(Percent(m.along_track.share_within[i]));
    rows.push_back(row);
  }
  const auto any_sigma = [&](auto get) {
    return std::any_of(eval.methods.begin(), eval.methods.end(),
                       [&](const MethodEvaluation& m) { return get(m).count > 0; });
  };
  const std::vector<
      std::pair<std::string, std::function<const Calibration&(const MethodEvaluation&)>>>
      calibrations = {
          {"<=2sigma [%]",
           [](const MethodEvaluation& m) -> const Calibration& { return m.along_calibration; }},
          {"horiz<=2sigma [%]", [](const MethodEvaluation& m) -> const Calibration& {
             return m.horizontal_calibration;
           }}};
  for (const auto& [label, get] : calibrations) {
    if (!any_sigma(get)) continue;
    TableRow row{label, {}};
    for (const auto& m : eval.methods) {
      row.cells.push_back(get(m).count > 0 ? Percent(get(m).share_within_2_sigma) : "-");
    }
    rows.push_back(row);
  }
  rows.push_back({"Frames", {}});
  using Count = std::function<int64_t(const MethodEvaluation&)>;
  std::vector<std::pair<std::string, Count>> counts = {
      {" rows", [](const MethodEvaluation& m) { return m.rows; }}};
  for (size_t s = 0; s < StatusNames().size(); ++s) {
    counts.push_back(
        {" " + StatusNames()[s], [s](const MethodEvaluation& m) { return m.by_status[s]; }});
  }
  counts.push_back({" unmatched", [](const MethodEvaluation& m) { return m.unmatched; }});
  counts.push_back({" evaluated", [](const MethodEvaluation& m) { return m.evaluated(); }});
  counts.push_back({" on route", [](const MethodEvaluation& m) { return m.truth_on_route; }});
  counts.push_back({"  localized", [](const MethodEvaluation& m) { return m.ok_on_route; }});
  counts.push_back(
      {" off route", [](const MethodEvaluation& m) { return m.truth_off_route; }});
  counts.push_back({"  localized", [](const MethodEvaluation& m) { return m.ok_off_route; }});
  for (const auto& [label, get] : counts) {
    TableRow row{label, {}};
    for (const auto& m : eval.methods) row.cells.push_back(std::to_string(get(m)));
    rows.push_back(row);
  }
  return rows;
}

std::vector<TableRow> OtherErrorRows(const Evaluation& eval) {
  using Stat = std::function<const ErrorStatistics&(const MethodEvaluation&)>;
  const std::vector<std::pair<std::string, Stat>> kinds = {
      {"Cross-track",
       [](const MethodEvaluation& m) -> const ErrorStatistics& { return m.cross_track; }},
      {"Horizontal",
       [](const MethodEvaluation& m) -> const ErrorStatistics& { return m.horizontal; }},
      {"Vertical", [](const MethodEvaluation& m) -> const ErrorStatistics& { return m.vertical; }},
      {"3-D", [](const MethodEvaluation& m) -> const ErrorStatistics& { return m.error_3d; }},
  };
  std::vector<TableRow> rows;
  for (const auto& [kind, stat] : kinds) {
    rows.push_back({kind, {}});
    const std::vector<std::pair<std::string, std::function<std::string(const ErrorStatistics&)>>>
        cells = {
            {" Mean|e|", [](const ErrorStatistics& s) { return Metres(s.mean_abs); }},
            {" Bias", [](const ErrorStatistics& s) { return Metres(s.bias); }},
            {" RMSE", [](const ErrorStatistics& s) { return Metres(s.rmse); }},
            {" P95|e|", [](const ErrorStatistics& s) { return Metres(s.p95_abs); }},
            {" <=0.5m [%]", [](const ErrorStatistics& s) { return Percent(s.share_within[2]); }},
            {" <=1m [%]", [](const ErrorStatistics& s) { return Percent(s.share_within[3]); }},
        };
    for (const auto& [label, format] : cells) {
      TableRow row{label, {}};
      for (const auto& m : eval.methods) row.cells.push_back(format(stat(m)));
      rows.push_back(row);
    }
  }
  // Orientation error, only when some method has orientations to compare.
  const bool any_rotation =
      std::any_of(eval.methods.begin(), eval.methods.end(),
                  [](const MethodEvaluation& m) { return m.rotation.count > 0; });
  if (any_rotation) {
    rows.push_back({"Rotation [deg]", {}});
    const std::vector<std::pair<std::string, std::function<std::string(const ErrorStatistics&)>>>
        cells = {
            {" Mean", [](const ErrorStatistics& s) { return Metres(s.mean_abs); }},
            {" Median", [](const ErrorStatistics& s) { return Metres(s.median_abs); }},
            {" RMSE", [](const ErrorStatistics& s) { return Metres(s.rmse); }},
            {" P95", [](const ErrorStatistics& s) { return Metres(s.p95_abs); }},
            {" Max", [](const ErrorStatistics& s) { return Metres(s.max); }},
            {" <=0.5deg [%]", [](const ErrorStatistics& s) { return Percent(s.share_within[2]); }},
            {" frames", [](const ErrorStatistics& s) { return std::to_string(s.count); }},
        };
    for (const auto& [label, format] : cells) {
      TableRow row{label, {}};
      for (const auto& m : eval.methods) row.cells.push_back(format(m.rotation));
      rows.push_back(row);
    }
  }
  return rows;
}

std::string AlongTrackTitle() {
  return "Along-track error [m] (estimate s - truth s along the route; + = estimate ahead)";
}
std::string OtherErrorsTitle() {
  return "Cross-track (+ = left of travel), horizontal, vertical (+ = above) and 3-D error [m]";
}

std::string FormatEvaluationTables(const Evaluation& eval) {
  return FormatTable(AlongTrackTitle(), AlongTrackRows(eval), eval) + "\n" +
         FormatTable(OtherErrorsTitle(), OtherErrorRows(eval), eval);
}

std::string EvaluationJson(const Evaluation& eval) {
  nlohmann::json j;
  j["association"] = AssociationName(eval.association);
  j["max_gap_s"] = eval.max_gap_s;
  j["route"] = {{"source", eval.route.source},
                {"length_m", eval.route_length_m},
                {"origin",
                 {{"lat_deg", eval.route.origin.lat_deg},
                  {"lon_deg", eval.route.origin.lon_deg},
                  {"alt_m", eval.route.origin.alt_m}}}};
  j["inputs"] = nlohmann::json::object();
  for (const auto& [label, value] : eval.inputs) j["inputs"][label] = value;
  j["thresholds_m"] = ErrorThresholds();
  j["percentile"] = "linear interpolation between order statistics (numpy default)";
  j["methods"] = nlohmann::json::array();
  for (const auto& m : eval.methods) {
    nlohmann::json counts = {{"rows", m.rows},
                             {"unmatched", m.unmatched},
                             {"evaluated", m.evaluated()},
                             {"not_localized", m.not_localized()},
                             {"truth_on_route", m.truth_on_route},
                             {"ok_on_route", m.ok_on_route},
                             {"truth_off_route", m.truth_off_route},
                             {"ok_off_route", m.ok_off_route}};
    for (size_t s = 0; s < StatusNames().size(); ++s) counts[StatusNames()[s]] = m.by_status[s];
    nlohmann::json unmatched = nlohmann::json::array();
    for (size_t i = 0; i < m.unmatched_frames.size(); ++i) {
      unmatched.push_back({{"frame", m.unmatched_frames[i] == kInvalidFrame
                                         ? nlohmann::json(nullptr)
                                         : nlohmann::json(m.unmatched_frames[i])},
                           {"timestamp_s", m.unmatched_times_s[i]}});
    }
    j["methods"].push_back(
        {{"method", m.method},
         {"counts", counts},
         {"unmatched_frames", unmatched},
         {"along_track_m", StatisticsJson(m.along_track)},
         {"cross_track_m", StatisticsJson(m.cross_track)},
         {"horizontal_m", StatisticsJson(m.horizontal)},
         {"vertical_m", StatisticsJson(m.vertical)},
         {"error_3d_m", StatisticsJson(m.error_3d)},
         {"rotation_deg", StatisticsJson(m.rotation)},
         {"calibration",
          {{"along_frames_with_sigma", m.along_calibration.count},
           {"along_within_2_sigma", m.along_calibration.share_within_2_sigma},
           {"horizontal_frames_with_sigma", m.horizontal_calibration.count},
           {"horizontal_within_2_sigma", m.horizontal_calibration.share_within_2_sigma}}}});
  }
  j["warnings"] = eval.warnings;
  return j.dump(2) + "\n";
}

void WriteEvaluationJson(const Evaluation& eval, const std::string& path) {
  CreateParentDirectory(path);
  AtomicOfstream out(path);
  out << EvaluationJson(eval);
  out.Commit();
}

void WriteFrameErrorsCsv(const Evaluation& eval, const std::string& path) {
  CreateParentDirectory(path);
  CsvWriter out(path, {"frame", "timestamp_s", "method", "truth_s_m", "estimate_s_m",
                       "along_track_m", "cross_track_m", "horizontal_m", "vertical_m", "error_3d_m",
                       "rotation_deg", "sigma_along_m", "sigma_horizontal_m"});
  for (const MethodEvaluation& m : eval.methods) {
    for (const FrameError& f : m.frames) {
      out.WriteRow({std::to_string(f.frame), FormatFixed(f.timestamp_s, 6), m.method,
                    FormatFixed(f.truth_s_m, 4), FormatFixed(f.estimate_s_m, 4),
                    FormatFixed(f.along_track_m, 4), FormatFixed(f.cross_track_m, 4),
                    FormatFixed(f.horizontal_m, 4), FormatFixed(f.vertical_m, 4),
                    FormatFixed(f.error_3d_m, 4), FormatFixed(f.rotation_deg, 4),
                    FormatFixed(f.sigma_along_m, 4), FormatFixed(f.sigma_horizontal_m, 4)});
    }
  }
  out.Close();
}

}  // namespace epiloc
