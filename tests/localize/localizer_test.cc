// The localizer end to end: a synthetic street with exact ground truth and the shared KITTI
// drive (the development scenario of the issue), evaluated with the eval module.
#include "epiloc/localize/stream.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/eval/evaluate.h"
#include "epiloc/eval/statistics.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/kitti.h"
#include "epiloc/survey/build_db.h"
#include "epiloc/synth/drive_gen.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  // Per process: the same test may run from another checkout at the same time.
  const fs::path dir = fs::temp_directory_path() /
                       ("epiloc_localizer_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

double ShareWithin(const ErrorStatistics& stats, double threshold) {
  const std::vector<double>& t = ErrorThresholds();
  for (size_t k = 0; k < t.size(); ++k) {
    if (t[k] == threshold) return stats.share_within[k];
  }
  ADD_FAILURE() << "no threshold " << threshold;
  return 0.0;
}

void Print(const Evaluation& evaluation) {
  for (const MethodEvaluation& m : evaluation.methods) {
    std::cout << m.method << ": along-track mean " << m.along_track.mean_abs << " m, max "
              << std::max(-m.along_track.min, m.along_track.max) << " m, <=0.5 m "
              << 100 * ShareWithin(m.along_track, 0.5) << " %, evaluated " << m.evaluated()
              << " of " << m.rows << "\n";
  }
}

double MaxAbs(const ErrorStatistics& stats) { return std::max(-stats.min, stats.max); }

TEST(Localizer, SyntheticStreetNoiseFreeQuery) {
  const fs::path dir = TempDir("synth");
  SynthOptions synth;
  synth.length_m = 70;
  synth.seed = 3;
  synth.lidar = false;
  synth.query.render = synth.survey.render;  // no noise, gain change or blur
  synth.query.exposure_s = 0.0;
  synth.query.wobble_yaw_deg = synth.query.wobble_pitch_deg = 0.0;
  synth.query.frame_rate_hz = 5.0;
  GenerateSynthetic(synth, dir.string());
  const std::string db = (dir / "route.sqlite").string();
  BuildDatabase((dir / "survey").string(), db, BuildDbOptions());

  LocalizeOptions options;
  options.all_methods = true;
  const LocalizeRun run = Localize(db, (dir / "query").string(), options);
  const Drive query = LoadDrive((dir / "query").string());
  const Evaluation evaluation =
      Evaluate(run.results, *query.ground_truth, RouteFromDatabase(db), EvaluateOptions());
  Print(evaluation);
  const MethodEvaluation* online = evaluation.Find("online");
  ASSERT_NE(online, nullptr);
  EXPECT_EQ(online->evaluated(), static_cast<int64_t>(query.frames.size()));
  EXPECT_LE(online->along_track.mean_abs, 0.05);
  EXPECT_LE(MaxAbs(online->along_track), 0.25);
  for (const char* method : {"fit_fixed", "fit_free"}) {
    const MethodEvaluation* fit = evaluation.Find(method);
    ASSERT_NE(fit, nullptr);
    EXPECT_LE(fit->along_track.mean_abs, 0.05) << method;
  }
  // The sub-frame fit beats the nearest database frame.
  EXPECT_LT(online->along_track.mean_abs, 0.5 * evaluation.Find("nearest")->along_track.mean_abs);
  // 6-DoF refinement against the triangulated survey (build-db triangulates by default).
  EXPECT_TRUE(run.refined);
  const MethodEvaluation* pnp = evaluation.Find("pnp");
  ASSERT_NE(pnp, nullptr);
  EXPECT_EQ(pnp->evaluated(), static_cast<int64_t>(query.frames.size()));
  EXPECT_EQ(run.num_refined_ok, static_cast<int>(query.frames.size()));
  EXPECT_LE(pnp->horizontal.mean_abs, 0.01);
  EXPECT_LE(pnp->rotation.mean_abs, 0.05);
  EXPECT_LE(MaxAbs(pnp->horizontal), 0.03);

  // The map's viewpoint error: the query drives beside the survey's line, and each pose's
  // horizontal sigma carries viewpoint_sigma_ratio times that offset, across the route, in
  // quadrature (compared with the same run without it; nothing else changes).
  LocalizeOptions exact = options;
  exact.viewpoint_sigma_ratio = 0.0;
  const LocalizeRun without = Localize(db, (dir / "query").string(), exact);
  ASSERT_EQ(without.results.rows.size(), run.results.rows.size());
  const auto column = [](const ResultTable& table, const std::string& name) {
    const auto& names = table.extra_columns;
    const auto it = std::find(names.begin(), names.end(), name);
    EXPECT_NE(it, names.end()) << name;
    return static_cast<size_t>(it - names.begin());
  };
  const size_t sigma_h = column(run.results, "sigma_horizontal_m");
  const size_t cross = column(run.results, "cross_track_m");
  int compared = 0;
  double largest_offset = 0.0;
  for (size_t i = 0; i < run.results.rows.size(); ++i) {
    const ResultRow& with_row = run.results.rows[i];
    const ResultRow& without_row = without.results.rows[i];
    ASSERT_EQ(with_row.method, without_row.method);
    ASSERT_EQ(with_row.position.lat_deg, without_row.position.lat_deg);
    if (with_row.method != "pnp" || with_row.extra[sigma_h].empty()) continue;
    const double offset = std::stod(with_row.extra[cross]);
    const double s1 = std::stod(with_row.extra[sigma_h]);
    const double s0 = std::stod(without_row.extra[sigma_h]);
    EXPECT_NEAR(s1 * s1 - s0 * s0, std::pow(options.viewpoint_sigma_ratio * offset, 2),
                2e-4 * (s1 + s0))
        << i;
    largest_offset = std::max(largest_offset, std::abs(offset));
    ++compared;
  }
  EXPECT_EQ(compared, static_cast<int>(query.frames.size()));
  EXPECT_GT(largest_offset, 0.3);  // the synthetic query keeps to another lane position
  fs::remove_all(dir);
}

// The development scenario: survey = camera 0, frames 0:154:2 (RTK); query = camera 1
// (0.54 m to the side), frames 1:154:2, GPS with 3 m noise, seed 1.
TEST(Localizer, KittiDevelopmentScenario) {
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  const fs::path dir = TempDir("kitti");
  KittiImportOptions survey;
  survey.raw_drive_dir = raw.string();
  survey.camera = 0;
  survey.start = 0;
  survey.step = 2;
  survey.out_dir = (dir / "survey").string();
  ImportKitti(survey);
  KittiImportOptions query = survey;
  query.camera = 1;
  query.start = 1;
  query.gps_noise_sigma_m = 3.0;
  query.seed = 1;
  query.out_dir = (dir / "query").string();
  ImportKitti(query);
  const std::string db = (dir / "route.sqlite").string();
  BuildDatabase(survey.out_dir, db, BuildDbOptions());

  LocalizeOptions options;
  options.all_methods = true;
  const LocalizeRun run = Localize(db, query.out_dir, options);
  const Drive query_drive = LoadDrive(query.out_dir);
  const Evaluation evaluation =
      Evaluate(run.results, *query_drive.ground_truth, RouteFromDatabase(db), EvaluateOptions());
  Print(evaluation);
  const MethodEvaluation* online = evaluation.Find("online");
  ASSERT_NE(online, nullptr);
  EXPECT_EQ(online->evaluated(), 77);
  // Targets: mean <= 0.15 m, max <= 1.0 m, >= 95 % within 0.5 m; reached 0.105 / 0.67 / 98.7 %.
  EXPECT_LE(online->along_track.mean_abs, 0.15);
  EXPECT_LE(MaxAbs(online->along_track), 1.0);
  EXPECT_GE(ShareWithin(online->along_track, 0.5), 0.95);
  const MethodEvaluation* fixed = evaluation.Find("fit_fixed");
  ASSERT_NE(fixed, nullptr);
  EXPECT_LE(fixed->along_track.mean_abs, 0.15);
  EXPECT_LE(MaxAbs(fixed->along_track), 1.0);
  // The gps baseline is what the localizer improves on.
  EXPECT_GT(evaluation.Find("gps")->along_track.mean_abs, 5 * online->along_track.mean_abs);
  // 6-DoF refinement (issue 8): every frame refined; reached along-track mean 0.039-0.043 m,
  // max 0.11-0.16 m, horizontal mean 0.072-0.078 m over 9 runs (FLANN's random trees vary runs;
  // COLMAP on the same frames: 0.042 / 0.152 / 0.088 m).
  const MethodEvaluation* pnp = evaluation.Find("pnp");
  ASSERT_NE(pnp, nullptr);
  EXPECT_EQ(pnp->evaluated(), 77);
  EXPECT_EQ(run.num_refined_ok, 77);
  EXPECT_LE(pnp->along_track.mean_abs, 0.05);
  EXPECT_LE(MaxAbs(pnp->along_track), 0.25);
  EXPECT_LE(pnp->horizontal.mean_abs, 0.09);
  EXPECT_LE(pnp->rotation.mean_abs, 0.30);
  EXPECT_LT(pnp->horizontal.mean_abs, 0.5 * online->horizontal.mean_abs);
  // Horizontal calibration (issue 16): camera 1 is 0.54 m beside the survey's line; the map pulls
  // it 2-3 cm toward that line (with the raw OXTS positions 0.15-0.35 m in the open square, and
  // 90.9 % within 2 sigma without a viewpoint term); 100 % within 2 sigma_horizontal_m.
  std::cout << "pnp within 2 sigma: along " << pnp->along_calibration.share_within_2_sigma
            << ", horizontal " << pnp->horizontal_calibration.share_within_2_sigma << "\n";
  EXPECT_GE(pnp->horizontal_calibration.share_within_2_sigma, 0.93);
  fs::remove_all(dir);
}

TEST(Localizer, BadInput) {
  EXPECT_THROW(ParseMode("sideways"), Error);
  EXPECT_EQ(ParseMode("free"), LocalizeOptions::Mode::kFree);
  LocalizeOptions options;
  options.track_window_m = 0;
  EXPECT_THROW(options.Check(), Error);
  // Issue 18 (unseen inputs): --off-route-m nan (or -5) was taken; with NaN no GPS fix, however far
  // from the route, could mark a frame off_route.
  for (const double off_route_m : {std::nan(""), -5.0, 0.0}) {
    LocalizeOptions off;
    off.off_route_m = off_route_m;
    EXPECT_THROW(off.Check(), Error) << off_route_m;
  }
  EXPECT_NO_THROW(LocalizeOptions().Check());
  EXPECT_THROW(Localize("/nonexistent/route.sqlite", "/nonexistent/drive", LocalizeOptions()),
               Error);
}

}  // namespace
}  // namespace epiloc
