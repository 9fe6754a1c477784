#include "epiloc/anchor/radial_calibration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <utility>

#include <spdlog/spdlog.h>

#include "epiloc/anchor/structure_sift.h"
#include "epiloc/core/error.h"
#include "epiloc/core/statistics.h"
#include "epiloc/io/drive.h"

namespace epiloc {

void RadialCalibrationOptions::Check() const {
  EPILOC_CHECK(std::isfinite(first_step) && first_step > 0.0, "first_step must be > 0");
  EPILOC_CHECK(std::isfinite(max_step) && max_step >= first_step,
               "max_step must be >= first_step");
  EPILOC_CHECK(std::isfinite(max_change) && max_change >= first_step,
               "max_change must be >= first_step");
  EPILOC_CHECK(std::isfinite(tolerance_percent_per_100m) && tolerance_percent_per_100m > 0.0,
               "tolerance_percent_per_100m must be > 0");
  EPILOC_CHECK(max_runs >= 2, "max_runs must be >= 2");
  EPILOC_CHECK(std::isfinite(min_distance_m) && min_distance_m >= 0.0,
               "min_distance_m must be >= 0");
  EPILOC_CHECK(sift_threads >= 1, "sift_threads must be >= 1");
  structure.Check();
}

int RadialTermIndex(RadialCalibrationOptions::Term term) {
  return term == RadialCalibrationOptions::Term::kK1 ? 0 : 1;
}

const char* RadialTermName(RadialCalibrationOptions::Term term) {
  return term == RadialCalibrationOptions::Term::kK1 ? "k1" : "k2";
}

namespace {

// Whether run `a` is closer to no trend than run `b` (a run without a trend is never closer).
bool CloserToNoTrend(const RadialCalibrationRun& a, const RadialCalibrationRun* b) {
  if (!a.trend) return false;
  return b == nullptr || !b->trend ||
         std::abs(a.trend->percent_per_100m) < std::abs(b->trend->percent_per_100m);
}

}  // namespace

RadialCalibrationResult SearchRadialTerm(
    double calibrated_term,
    const RadialCalibrationOptions& options,
    const std::function<RadialCalibrationRun(double term)>& measure) {
  options.Check();
  RadialCalibrationResult result;
  result.term = calibrated_term;
  const auto trend_of = [](const RadialCalibrationRun& run) {
    return run.trend->percent_per_100m;
  };
  double term = calibrated_term;
  while (static_cast<int>(result.runs.size()) < options.max_runs) {
    RadialCalibrationRun run = measure(term);
    run.term = term;
    result.runs.push_back(run);
    if (!run.trend) {
      result.message = fmt::format("{} = {:+.4f}: no scale trend ({})", RadialTermName(options.term), term,
                                   run.message.empty() ? "too few ok anchors" : run.message);
      break;
    }
    const int index = static_cast<int>(result.runs.size()) - 1;
    if (CloserToNoTrend(run, result.best_run < 0 ? nullptr : &result.runs[result.best_run])) {
      result.best_run = index;
    }
    if (std::abs(trend_of(run)) <= options.tolerance_percent_per_100m) {
      result.converged = true;
      break;
    }
    double next;
    if (index == 0) {
      // A larger term raises the trend (header): step against the trend's sign.
      next = term + (trend_of(run) < 0.0 ? options.first_step : -options.first_step);
    } else {
      const RadialCalibrationRun& before = result.runs[index - 1];
      const double ds = trend_of(run) - trend_of(before);
      if (!(std::abs(ds) > 0.0)) {
        result.message = fmt::format("two runs ({:+.4f}, {:+.4f}) measured the same trend",
                                     before.term, run.term);
        break;
      }
      next = term - trend_of(run) * (run.term - before.term) / ds;
    }
    next = std::clamp(next, term - options.max_step, term + options.max_step);
    next = std::clamp(next, calibrated_term - options.max_change,
                      calibrated_term + options.max_change);
    if (std::abs(next - term) < 1e-6) {
      result.message = fmt::format(
          "the trend asks for a term beyond {:+.4f} (at most {:.3f} from the calibration's)", term,
          options.max_change);
      break;
    }
    term = next;
  }
  if (!result.converged && result.message.empty()) {
    result.message = fmt::format("no run within {:.1f} % per 100 m in {} runs",
                                 options.tolerance_percent_per_100m, result.runs.size());
  }
  if (result.best_run >= 0) result.term = result.runs[result.best_run].term;
  return result;
}

RadialCalibrationResult CalibrateRadialTerm(
    const AnchorInputs& inputs,
    const RadialCalibrationOptions& options,
    const std::string& work_dir,
    const std::function<void(const RadialCalibrationRun&)>& on_run,
    const ProgressCallback& progress) {
  options.Check();
  inputs.Check();
  const Drive drive = LoadDrive(inputs.drive_dir);
  const int k = RadialTermIndex(options.term);
  std::filesystem::create_directories(work_dir);
  int runs_done = 0;
  std::optional<std::pair<RadialCalibrationRun, VoResult>> best;  // closest to no trend, its VO
  const auto measure = [&](double term) {
    const auto start = std::chrono::steady_clock::now();
    Drive candidate = drive;
    candidate.camera.distortion[k] = term;
    candidate.camera.Check(fmt::format("{} = {:+.4f}", RadialTermName(options.term), term));
    const std::string dir =
        (std::filesystem::path(work_dir) / fmt::format("run_{}", runs_done + 1)).string();
    WriteDrive(candidate, dir);
    candidate = LoadDrive(dir);
    const VoResult vo_result = RunVisualOdometry(candidate, options.vo);
    const VoStructure vo = VoStructure::FromResult(vo_result);
    AnchorInputs run_inputs = inputs;
    run_inputs.drive_dir = dir;
    run_inputs.vo_path.clear();
    const auto sift_structure = [&] {
      BuildDbOptions build;
      build.num_threads = options.sift_threads;
      return TriangulateAlongVo(dir, vo, build);
    };
    const AnchorDriveResult anchors =
        AnchorDriveByStructureAuto(run_inputs, vo, sift_structure, options.structure);
    RadialCalibrationRun run;
    run.term = term;
    run.anchors = static_cast<int>(anchors.frames.size());
    std::vector<double> residuals;
    for (const AnchorResult& a : anchors.frames) {
      if (a.status != AnchorStatus::kOk) continue;
      ++run.ok_anchors;
      if (std::isfinite(a.residual_m)) residuals.push_back(a.residual_m);
    }
    run.median_residual_m = UpperMedian(std::move(residuals));
    run.trend = ScaleTrendOfAnchors(anchors, [&vo](frame_t f) { return vo.SegmentOf(f); });
    if (!run.trend) {
      run.message = fmt::format("{} of {} anchors ok, fewer than 3 or within 10 m",
                                run.ok_anchors, run.anchors);
    } else if (run.trend->distance_m < options.min_distance_m) {
      run.message = fmt::format("the ok anchors span {:.0f} m, less than {:.0f} m",
                                run.trend->distance_m, options.min_distance_m);
      run.trend.reset();
    }
    run.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ++runs_done;
    if (run.trend) {
      spdlog::info("{} = {:+.4f}: {} of {} anchors ok, VO scale {:+.1f} % per 100 m over {:.0f} m "
                   "({:.0f} s)",
                   RadialTermName(options.term), term, run.ok_anchors, run.anchors,
                   run.trend->percent_per_100m, run.trend->distance_m, run.seconds);
    } else {
      spdlog::info("{} = {:+.4f}: {} ({:.0f} s)", RadialTermName(options.term), term,
                   run.message, run.seconds);
    }
    if (CloserToNoTrend(run, best ? &best->first : nullptr)) best.emplace(run, vo_result);
    if (on_run) on_run(run);
    if (progress) progress(runs_done, options.max_runs);
    return run;
  };
  RadialCalibrationResult result = SearchRadialTerm(drive.camera.distortion[k], options, measure);
  result.camera = drive.camera;
  result.camera.distortion[k] = result.term;
  if (best) result.vo = std::move(best->second);
  return result;
}

}  // namespace epiloc
