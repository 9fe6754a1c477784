#include "epiloc/eval/report.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "eval_test_util.h"

namespace epiloc {
namespace {

using V = Eigen::Vector3d;

// Straight road east; gps errors +0.4, -0.8, +3 m along, pnp +0.1 m, and one lost pnp frame.
Evaluation SmallEvaluation() {
  const PositionTrack truth =
      TrackFromEnu({V(0, 0, 0), V(10, 0, 0), V(20, 0, 0), V(30, 0, 0)}, {0, 1, 2, 3}, true);
  ResultTable result;
  result.path = "r.csv";
  result.rows.push_back(OkRow("gps", 0, 0, V(0.4, 0, 0)));
  result.rows.push_back(OkRow("gps", 1, 1, V(9.2, 0, 0)));
  result.rows.push_back(OkRow("gps", 2, 2, V(23, 0, 0)));
  result.rows.push_back(OkRow("pnp", 1, 1, V(10.1, 0, 0)));
  result.rows.push_back(StatusRow("pnp", 2, 2, ResultStatus::kLost));
  Evaluation eval = Evaluate(result, truth, RouteFromTrack(truth), EvaluateOptions());
  eval.inputs.emplace_back("result", "r.csv <test>");
  return eval;
}

TEST(Report, TableHasPaperLayout) {
  const std::string table = FormatEvaluationTables(SmallEvaluation());
  std::istringstream in(table);
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(in, line)) lines.push_back(line);
  ASSERT_GT(lines.size(), 10u);
  EXPECT_NE(lines[0].find("Along-track error"), std::string::npos);
  EXPECT_NE(lines[1].find("gps"), std::string::npos);
  EXPECT_LT(lines[1].find("gps"), lines[1].find("pnp"));
  // gps along-track +0.4, -0.8, +3 (|e| sorted 0.4, 0.8, 3): min -0.8, max 3, mean |e| 4.2/3 =
  // 1.4, bias 2.6/3 = 0.867, std sqrt(9.8/3 - 0.867^2) = 1.586, median 0.8, RMSE sqrt(9.8/3) =
  // 1.807, P95 (h = 1.9) 0.8 + 0.9 * 2.2 = 2.78, shares 0, 0, 1/3, 2/3, 2/3.
  EXPECT_NE(table.find("Min              -0.800     0.100"), std::string::npos) << table;
  EXPECT_NE(table.find("Max               3.000"), std::string::npos) << table;
  EXPECT_NE(table.find("Mean|e|           1.400"), std::string::npos) << table;
  EXPECT_NE(table.find("Bias              0.867"), std::string::npos) << table;
  EXPECT_NE(table.find("Std               1.586     0.000"), std::string::npos) << table;
  EXPECT_NE(table.find("Median|e|         0.800"), std::string::npos) << table;
  EXPECT_NE(table.find("RMSE              1.807"), std::string::npos) << table;
  EXPECT_NE(table.find("P95|e|            2.780"), std::string::npos) << table;
  EXPECT_NE(table.find("<=0.25m [%]         0.0     100.0"), std::string::npos) << table;
  EXPECT_NE(table.find("<=0.5m [%]         33.3     100.0"), std::string::npos) << table;
  EXPECT_NE(table.find("<=1m [%]           66.7     100.0"), std::string::npos) << table;
  EXPECT_NE(table.find(" lost                 0         1"), std::string::npos) << table;
  EXPECT_NE(table.find(" evaluated            3         1"), std::string::npos) << table;
  EXPECT_EQ(table.find("-0.000"), std::string::npos) << table;
  EXPECT_NE(table.find("Cross-track"), std::string::npos);
}

TEST(Report, JsonHasAllMethodsMetricsAndCounts) {
  const Evaluation eval = SmallEvaluation();
  const auto j = nlohmann::json::parse(EvaluationJson(eval));
  EXPECT_EQ(j["association"], "frame");
  ASSERT_EQ(j["methods"].size(), 2u);
  const auto& gps = j["methods"][0];
  EXPECT_EQ(gps["method"], "gps");
  EXPECT_NEAR(gps["along_track_m"]["bias"].get<double>(), 2.6 / 3.0, 1e-6);
  EXPECT_NEAR(gps["along_track_m"]["p95_abs"].get<double>(), 2.78, 1e-6);
  EXPECT_NEAR(gps["along_track_m"]["min"].get<double>(), -0.8, 1e-6);
  EXPECT_NEAR(gps["along_track_m"]["share_within"]["1"].get<double>(), 2.0 / 3.0, 1e-9);
  const auto& pnp = j["methods"][1];
  EXPECT_EQ(pnp["counts"]["lost"], 1);
  EXPECT_EQ(pnp["counts"]["evaluated"], 1);
  EXPECT_EQ(pnp["counts"]["unmatched"], 0);
  EXPECT_TRUE(pnp["unmatched_frames"].empty());
  EXPECT_TRUE(pnp["cross_track_m"]["std"].is_number());
  EXPECT_EQ(j["inputs"]["result"], "r.csv <test>");
}

TEST(Report, HtmlIsSelfContained) {
  if (!GnuplotAvailable("gnuplot")) GTEST_SKIP() << "gnuplot not installed";
  TempDir dir;
  const Evaluation eval = SmallEvaluation();
  WriteHtmlReport(eval, dir / "out/report.html", ReportOptions());
  std::ifstream in(dir / "out/report.html");
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string html = buffer.str();
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  size_t svgs = 0;
  for (size_t p = html.find("<svg"); p != std::string::npos; p = html.find("<svg", p + 1)) ++svgs;
  EXPECT_EQ(svgs, 3u);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_EQ(html.find(" src="), std::string::npos);
  EXPECT_EQ(html.find("<?xml"), std::string::npos);
  EXPECT_NE(html.find("r.csv &lt;test&gt;"), std::string::npos);  // inputs, escaped
  EXPECT_NE(html.find("<td>1.400</td>"), std::string::npos);
  for (const char* name :
       {"cdf.svg", "along_route.svg", "top_view.svg", "plots.gp", "cdf_gps.dat"}) {
    EXPECT_TRUE(std::filesystem::exists(dir / (std::string("out/report_files/") + name))) << name;
  }
}

TEST(Report, MissingGnuplotIsAClearError) {
  TempDir dir;
  ReportOptions options;
  options.gnuplot = dir / "no/gnuplot";
  EXPECT_FALSE(GnuplotAvailable(options.gnuplot));
  ExpectError([&] { WriteHtmlReport(SmallEvaluation(), dir / "r.html", options); },
              {"gnuplot not found", "gnuplot-nox"});
}

}  // namespace
}  // namespace epiloc
