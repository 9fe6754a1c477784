// The survey chain without RTK on the shared KITTI drive (skipped without ../shared/data), the
// development scenario of issues 6 and 7: a LiDAR map from camera 0's drive; camera 1 (all
// frames, --gps-noise 3) anchored in it every 5th frame against camera 0's photographs; monocular
// VO of camera 1 georeferenced by those anchors; a route database from the georeferenced
// trajectory; a camera-0 query (frames 1:154:2) localized against it. Each stage is evaluated
// against the OXTS ground truth and asserts the accuracy reached.
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "epiloc/anchor/anchor.h"
#include "epiloc/anchor/build_map.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/eval/evaluate.h"
#include "epiloc/eval/statistics.h"
#include "epiloc/georef/georef.h"
#include "epiloc/georef/trajectory_import.h"
#include "epiloc/io/kitti.h"
#include "epiloc/io/result.h"
#include "epiloc/localize/stream.h"
#include "epiloc/survey/build_db.h"
#include "epiloc/vo/visual_odometry.h"
#include "pipeline_test_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

const MethodEvaluation& Method(const Evaluation& evaluation, const std::string& name) {
  const MethodEvaluation* m = evaluation.Find(name);
  EXPECT_NE(m, nullptr) << name;
  static const MethodEvaluation kNone;
  return m != nullptr ? *m : kNone;
}

double MaxAbs(const ErrorStatistics& stats) { return std::max(-stats.min, stats.max); }

TEST(PipelineKitti, MapAnchorsVoGeorefDatabaseLocalize) {
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  TempDir dir;
  KittiImportOptions cam0;
  cam0.raw_drive_dir = raw.string();
  cam0.camera = 0;
  cam0.out_dir = dir / "cam0";
  ImportKitti(cam0);
  KittiImportOptions cam1 = cam0;
  cam1.camera = 1;
  cam1.gps_noise_sigma_m = 3.0;
  cam1.seed = 1;
  cam1.out_dir = dir / "cam1";
  ImportKitti(cam1);
  KittiImportOptions query = cam0;
  query.start = 1;
  query.step = 2;
  query.gps_noise_sigma_m = 3.0;
  query.out_dir = dir / "query";
  ImportKitti(query);
  const Drive survey = LoadDrive(cam1.out_dir);

  // Anchors.
  const std::string map = dir / "map.ply";
  BuildMap(cam0.out_dir, map, std::nullopt, "", BuildMapOptions());
  AnchorInputs anchor_inputs;
  anchor_inputs.cloud_path = map;
  anchor_inputs.map_origin = ReadMapSidecar(SidecarPath(map)).enu_origin;
  anchor_inputs.drive_dir = cam1.out_dir;
  anchor_inputs.every = 5;
  anchor_inputs.photos_dir = cam0.out_dir;
  AnchorOptions anchor_options;
  anchor_options.heading_error_deg = 5.0;
  const AnchorDriveResult anchored = AnchorDrive(anchor_inputs, anchor_options);
  const AnchorSet anchors = OkAnchors(anchored);
  EXPECT_GE(anchors.anchors.size(), 28u);  // of 31; reached 31

  // VO and georeferencing.
  const VoResult vo = RunVisualOdometry(survey, VoOptions());
  const std::string vo_path = dir / "vo.tum";
  WriteVoTrajectory(vo, vo_path);
  const ImportedTrajectory trajectory = ImportTrajectory(vo_path, TrajectoryImportOptions());
  std::vector<GeorefFrame> frames;
  for (const FrameRecord& f : survey.frames) frames.push_back({f.frame, f.timestamp_s});
  GeorefOptions georef_options;
  georef_options.methods = {GeorefMethod::kPaper, GeorefMethod::kSim3, GeorefMethod::kPiecewise};
  const GeorefResult georef = Georeference(trajectory, anchors, frames, georef_options);
  const double paper_max = MaxHorizontal(georef.table, "paper", survey);
  const double sim3_max = MaxHorizontal(georef.table, "sim3", survey);
  const double piecewise_max = MaxHorizontal(georef.table, "piecewise", survey);
  std::printf("georef horizontal max: paper %.3f m, sim3 %.3f m, piecewise %.3f m\n", paper_max,
              sim3_max, piecewise_max);
  // Targets: paper <= 1.3 m, piecewise <= 0.3 m. Reached: paper 1.83 m, sim3 1.24 m, piecewise
  // 0.283 m (the anchors' own error in the turn, frames 60-70, which piecewise passes through;
  // 0.325 m with anchors every 10th frame); on 2026-11-28 paper 1.737 m, sim3 1.337 m,
  // piecewise 0.062 m (the photographs' anchors better since).
  EXPECT_LE(paper_max, 2.5);
  EXPECT_LE(piecewise_max, 0.2);
  EXPECT_LT(piecewise_max, paper_max);

  // A database from the piecewise trajectory, and a camera-0 query localized against it.
  ResultTable positions;
  for (const ResultRow& r : georef.table.rows) {
    if (r.method == "piecewise") positions.rows.push_back(r);
  }
  positions.extra_columns = georef.table.extra_columns;
  for (ResultRow& r : positions.rows) r.extra.resize(positions.extra_columns.size());
  const std::string positions_path = dir / "trajectory.csv";
  WriteResultCsv(positions, positions_path);
  BuildDbOptions build;
  build.positions = positions_path;
  const std::string db = dir / "route.sqlite";
  BuildDatabase(cam1.out_dir, db, build);
  const LocalizeRun run = Localize(db, query.out_dir, LocalizeOptions());
  const Drive query_drive = LoadDrive(query.out_dir);
  const Evaluation evaluation =
      Evaluate(run.results, *query_drive.ground_truth, RouteFromDatabase(db), EvaluateOptions());
  const MethodEvaluation& online = Method(evaluation, "online");
  std::printf("query online along-track mean %.3f m, max %.3f m\n", online.along_track.mean_abs,
              MaxAbs(online.along_track));
  // Target: mean <= 0.25 m; reached 0.094-0.098 m with the DTW tracker, 0.044 m with the
  // evidence-weighted one (issue 16), which reports a frame only once its evidence agrees: 76 or
  // 77 of 77 frames (>= 95 %, the suite's target); on 2026-11-28 0.021 m, max 0.066 m.
  EXPECT_GE(online.evaluated() * 100, 77 * 95);
  EXPECT_LE(online.along_track.mean_abs, 0.1);
}

}  // namespace
}  // namespace epiloc
