// The gps baseline of the shared KITTI drive 0005 (simulated 3 m GNSS noise) against its OXTS
// ground truth, through the library as `epiloc evaluate` runs it.
#include <filesystem>

#include <gtest/gtest.h>

#include "epiloc/eval/evaluate.h"
#include "epiloc/eval/report.h"
#include "epiloc/io/kitti.h"
#include "eval_test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

const std::string kRawDrive = KittiRawDrive().string();

TEST(KittiEvaluation, GpsBaselineMatchesTheSimulatedNoise) {
  if (!fs::is_directory(kRawDrive)) {
    GTEST_SKIP() << "KITTI raw drive not found at " << kRawDrive << "; skipping real-data test";
  }
  TempDir dir;
  KittiImportOptions import;
  import.raw_drive_dir = kRawDrive;
  import.gps_noise_sigma_m = 3.0;
  import.seed = 1;
  import.out_dir = dir / "drive";
  const Drive drive = ImportKitti(import);

  EvaluateInputs inputs;
  inputs.truth_path = dir / "drive";
  inputs.gnss_drive_dir = dir / "drive";
  const Evaluation eval = EvaluateFiles(inputs);
  ASSERT_EQ(eval.methods.size(), 1u);
  const MethodEvaluation& gps = eval.methods[0];
  EXPECT_EQ(gps.method, "gps");
  EXPECT_EQ(gps.evaluated(), static_cast<int64_t>(drive.frames.size()));
  EXPECT_EQ(gps.unmatched, 0);
  // sigma 3 m per horizontal axis: |along| averages ~0.8 sigma when the error is white; the
  // Gauss-Markov bias makes it vary between seeds, but never outside these bounds.
  EXPECT_GT(gps.along_track.mean_abs, 0.3);
  EXPECT_LT(gps.along_track.mean_abs, 10.0);
  EXPECT_GT(gps.horizontal.mean_abs, 0.5);
  EXPECT_LT(gps.horizontal.mean_abs, 15.0);
  // The route is the ground-truth track of the ~70 m drive; the truth lies on it.
  EXPECT_GT(eval.route_length_m, 60.0);
  EXPECT_LT(eval.route_length_m, 80.0);
  EXPECT_LT(std::abs(eval.truth_s_m.front()), 1e-6);

  // OXTS folder as ground truth, by time, moved to camera 0 by the lever arm: the same within a
  // few centimetres as the drive's camera-centred truth.
  EvaluateInputs oxts = inputs;
  oxts.truth_path = kRawDrive + "/oxts";
  oxts.truth.lever_arm_m = Eigen::Vector3d(1.08, -0.32, 0.73);
  const Evaluation by_oxts = EvaluateFiles(oxts);
  EXPECT_NEAR(by_oxts.methods[0].horizontal.mean_abs, gps.horizontal.mean_abs, 0.05);
  if (GnuplotAvailable("gnuplot")) {
    WriteHtmlReport(eval, dir / "report.html", ReportOptions());
    EXPECT_TRUE(fs::exists(dir / "report_files/top_view.svg"));
  }
}

}  // namespace
}  // namespace epiloc
