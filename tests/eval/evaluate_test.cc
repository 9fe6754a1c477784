#include "epiloc/eval/evaluate.h"

#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "epiloc/db/database.h"
#include "epiloc/eval/report.h"
#include "epiloc/io/kitti.h"
#include "eval_test_util.h"

namespace epiloc {
namespace {

using V = Eigen::Vector3d;

// An L: 10 m east, then 10 m north. s = 0 at the origin, 10 at the corner, 20 at the end.
EvaluationRoute LRoute() { return {TestOrigin(), {V(0, 0, 0), V(10, 0, 0), V(10, 10, 0)}, "L"}; }

// Ground truth on the L at t = 0..5 s, frames 0..5: s = 0, 5, 10, 12, 15, 20.
PositionTrack LTruth(bool with_frames = true) {
  return TrackFromEnu({V(0, 0, 0), V(5, 0, 0), V(10, 0, 0), V(10, 2, 0), V(10, 5, 0), V(10, 10, 0)},
                      {0, 1, 2, 3, 4, 5}, with_frames);
}

const FrameError& FrameAt(const MethodEvaluation& m, frame_t frame) {
  for (const auto& f : m.frames) {
    if (f.frame == frame) return f;
  }
  throw Error("frame not evaluated");
}

TEST(Evaluate, SignConventionsOnAnLShapedRoute) {
  ResultTable result;
  result.path = "r.csv";
  // Truth at s = 5 (first leg, travel east; left = north).
  result.rows.push_back(OkRow("pnp", 1, 1, V(7, 0.5, 1.5)));  // 2 m ahead, 0.5 m left, 1.5 m up
  // Truth at s = 15 (second leg, travel north; left = west).
  result.rows.push_back(OkRow("pnp", 4, 4, V(9, 3, 0)));  // 2 m behind, 1 m left
  result.rows.push_back(OkRow("vo", 4, 4, V(11, 5, 0)));  // level, 1 m right
  // Truth at s = 12 after the corner; estimate 2 m before the corner on the first leg: s = 8.
  result.rows.push_back(OkRow("vo", 3, 3, V(8, 0, 0)));
  const Evaluation eval = Evaluate(result, LTruth(), LRoute(), EvaluateOptions());
  EXPECT_EQ(eval.association, Association::kFrame);
  EXPECT_NEAR(eval.route_length_m, 20.0, 1e-9);
  const MethodEvaluation* pnp = eval.Find("pnp");
  const MethodEvaluation* vo = eval.Find("vo");
  ASSERT_TRUE(pnp && vo);

  const FrameError& a = FrameAt(*pnp, 1);
  EXPECT_NEAR(a.truth_s_m, 5.0, 1e-6);
  EXPECT_NEAR(a.along_track_m, 2.0, 1e-6);
  EXPECT_NEAR(a.cross_track_m, 0.5, 1e-6);
  EXPECT_NEAR(a.horizontal_m, 2.0615528128, 1e-6);  // sqrt(2^2 + 0.5^2)
  EXPECT_NEAR(a.vertical_m, 1.5, 1e-6);
  EXPECT_NEAR(a.error_3d_m, 2.5495097568, 1e-6);  // sqrt(4 + 0.25 + 2.25)

  const FrameError& b = FrameAt(*pnp, 4);
  EXPECT_NEAR(b.truth_s_m, 15.0, 1e-6);
  EXPECT_NEAR(b.along_track_m, -2.0, 1e-6);
  EXPECT_NEAR(b.cross_track_m, 1.0, 1e-6);
  EXPECT_NEAR(FrameAt(*vo, 4).cross_track_m, -1.0, 1e-6);
  EXPECT_NEAR(FrameAt(*vo, 4).along_track_m, 0.0, 1e-6);
  const FrameError& c = FrameAt(*vo, 3);
  EXPECT_NEAR(c.truth_s_m, 12.0, 1e-6);
  EXPECT_NEAR(c.estimate_s_m, 8.0, 1e-6);
  EXPECT_NEAR(c.along_track_m, -4.0, 1e-6);
  EXPECT_NEAR(c.horizontal_m, std::sqrt(8.0), 1e-6);  // (8, 0) - (10, 2)

  // pnp along-track errors +2 and -2: bias 0, mean |e| 2, RMSE 2, min -2, max +2.
  EXPECT_EQ(pnp->along_track.count, 2);
  EXPECT_NEAR(pnp->along_track.bias, 0.0, 1e-6);
  EXPECT_NEAR(pnp->along_track.mean_abs, 2.0, 1e-6);
  EXPECT_NEAR(pnp->along_track.rmse, 2.0, 1e-6);
  EXPECT_NEAR(pnp->along_track.min, -2.0, 1e-6);
  EXPECT_NEAR(pnp->along_track.max, 2.0, 1e-6);
  EXPECT_NEAR(pnp->cross_track.bias, 0.75, 1e-6);  // (0.5 + 1) / 2
  // Methods in KnownMethods() order (pnp before vo).
  ASSERT_EQ(eval.methods.size(), 2u);
  EXPECT_EQ(eval.methods[0].method, "pnp");
  EXPECT_EQ(eval.methods[1].method, "vo");
}

TEST(Evaluate, InterpolatesGroundTruthAtRowTimes) {
  // Truth every 2 s along a straight road east: x = 5 t.
  const PositionTrack truth =
      TrackFromEnu({V(0, 0, 0), V(10, 0, 0), V(20, 0, 0)}, {0, 2, 4}, false);
  ResultTable result;
  result.path = "r.csv";
  result.rows.push_back(OkRow("online", 7, 0.5, V(3.0, 0, 0)));   // truth 2.5 -> +0.5
  result.rows.push_back(OkRow("online", 8, 3.1, V(15.0, 0, 0)));  // truth 15.5 -> -0.5
  EvaluateOptions options;
  options.max_gap_s = 1.5;
  const Evaluation eval = Evaluate(result, truth, RouteFromTrack(truth), options);
  EXPECT_EQ(eval.association, Association::kTime);  // truth has no frame numbers
  const MethodEvaluation& m = eval.methods.at(0);
  ASSERT_EQ(m.evaluated(), 2);
  EXPECT_NEAR(m.frames[0].truth_s_m, 2.5, 1e-6);
  EXPECT_NEAR(m.frames[0].along_track_m, 0.5, 1e-6);
  EXPECT_NEAR(m.frames[1].truth_s_m, 15.5, 1e-6);
  EXPECT_NEAR(m.frames[1].along_track_m, -0.5, 1e-6);
  EXPECT_NEAR((m.frames[1].truth_in_enu - V(15.5, 0, 0)).norm(), 0.0, 1e-6);
}

TEST(Evaluate, CountsUnmatchedAndNotLocalizedFramesPerMethod) {
  const PositionTrack truth = LTruth(false);  // t = 0..5 s, no frame numbers
  ResultTable result;
  result.path = "r.csv";
  result.rows.push_back(OkRow("gps", 0, 1.0, V(5, 0, 0)));
  result.rows.push_back(OkRow("gps", 1, 5.6, V(10, 10, 0)));  // 0.6 s after the last truth
  result.rows.push_back(OkRow("dtw_free", 0, 1.0, V(5, 0, 0)));
  result.rows.push_back(OkRow("dtw_free", 1, -0.5, V(0, 0, 0)));  // 0.5 s before the first
  result.rows.push_back(OkRow("dtw_free", 2, 9.0, V(10, 10, 0)));
  result.rows.push_back(StatusRow("dtw_free", 3, 2.0, ResultStatus::kLost));
  result.rows.push_back(StatusRow("dtw_free", 4, 3.0, ResultStatus::kOffRoute));
  result.rows.push_back(StatusRow("dtw_free", 5, 3.0, ResultStatus::kSkipped));
  EvaluateOptions options;
  options.max_gap_s = 0.25;
  options.association = Association::kAuto;
  const Evaluation eval = Evaluate(result, truth, LRoute(), options);
  ASSERT_EQ(eval.methods.size(), 2u);
  const MethodEvaluation& gps = *eval.Find("gps");
  const MethodEvaluation& dtw = *eval.Find("dtw_free");
  EXPECT_EQ(gps.rows, 2);
  EXPECT_EQ(gps.unmatched, 1);
  EXPECT_EQ(gps.unmatched_frames, (std::vector<frame_t>{1}));
  EXPECT_EQ(gps.evaluated(), 1);
  EXPECT_EQ(dtw.rows, 6);
  EXPECT_EQ(dtw.ok(), 3);
  EXPECT_EQ(dtw.unmatched, 2);
  EXPECT_EQ(dtw.unmatched_frames, (std::vector<frame_t>{1, 2}));
  EXPECT_EQ(dtw.by_status[static_cast<size_t>(ResultStatus::kLost)], 1);
  EXPECT_EQ(dtw.by_status[static_cast<size_t>(ResultStatus::kOffRoute)], 1);
  EXPECT_EQ(dtw.by_status[static_cast<size_t>(ResultStatus::kSkipped)], 1);
  EXPECT_EQ(dtw.not_localized(), 3);
  EXPECT_EQ(dtw.evaluated(), 1);
  ASSERT_EQ(eval.warnings.size(), 2u);  // one per method with unmatched frames
  EXPECT_NE(eval.warnings[0].find("gps: 1 of 2"), std::string::npos) << eval.warnings[0];
  EXPECT_NE(eval.warnings[1].find("dtw_free: 2 of 3"), std::string::npos) << eval.warnings[1];
}

// Frames the vehicle drove before, beside or after the surveyed route are counted apart: there
// lost / off_route is the right answer (issue 16: the localized share of a query that leaves the
// route).
TEST(Evaluate, CountsFramesWhoseTruthIsOffTheRouteApart) {
  // Truth along x: 3 m before the route's start, on it (2 frames), 3 m and 8 m beside it at the
  // corner, 4 m beyond its end (frames 0..5 at t = 0..5 s).
  const PositionTrack truth = TrackFromEnu(
      {V(-3, 0, 0), V(2, 0, 0), V(10, 5, 0), V(13, 5, 0), V(18, 5, 0), V(10, 14, 0)},
      {0, 1, 2, 3, 4, 5}, true);
  ResultTable result;
  result.path = "r.csv";
  result.rows.push_back(OkRow("online", 0, 0.0, V(0, 0, 0)));                // off (before), ok
  result.rows.push_back(OkRow("online", 1, 1.0, V(2, 0, 0)));                // on, ok
  result.rows.push_back(StatusRow("online", 2, 2.0, ResultStatus::kLost));   // on, lost
  result.rows.push_back(OkRow("online", 3, 3.0, V(10, 5, 0)));               // 3 m beside: on
  result.rows.push_back(StatusRow("online", 4, 4.0, ResultStatus::kOffRoute));  // 8 m beside
  result.rows.push_back(StatusRow("online", 5, 5.0, ResultStatus::kOffRoute));  // beyond the end
  EvaluateOptions options;
  const Evaluation eval = Evaluate(result, truth, LRoute(), options);
  const MethodEvaluation& m = *eval.Find("online");
  EXPECT_EQ(m.truth_on_route, 3);
  EXPECT_EQ(m.ok_on_route, 2);
  EXPECT_EQ(m.truth_off_route, 3);
  EXPECT_EQ(m.ok_off_route, 1);
  // A wider band takes the frame 8 m beside the route in.
  options.on_route_m = 10.0;
  const Evaluation wider = Evaluate(result, truth, LRoute(), options);
  const MethodEvaluation& wide = *wider.Find("online");
  EXPECT_EQ(wide.truth_on_route, 4);
  EXPECT_EQ(wide.truth_off_route, 2);
  options.on_route_m = -1.0;
  EXPECT_THROW(Evaluate(result, truth, LRoute(), options), Error);
}

TEST(Evaluate, FrameAssociationMatchesByNumber) {
  ResultTable result;
  result.path = "r.csv";
  // Times deliberately off: association by frame ignores them.
  result.rows.push_back(OkRow("anchor", 1, 100.0, V(5.5, 0, 0)));  // truth frame 1 at s = 5
  result.rows.push_back(OkRow("anchor", 9, 101.0, V(5.5, 0, 0)));  // no frame 9
  const Evaluation eval = Evaluate(result, LTruth(true), LRoute(), EvaluateOptions());
  EXPECT_EQ(eval.association, Association::kFrame);
  const MethodEvaluation& m = eval.methods.at(0);
  ASSERT_EQ(m.evaluated(), 1);
  EXPECT_NEAR(m.frames[0].along_track_m, 0.5, 1e-6);
  EXPECT_EQ(m.unmatched_frames, (std::vector<frame_t>{9}));
}

// Issue 18 item 9: another tool's method name is evaluated; frame numbers matching rows whose
// times are days apart get a warning.
TEST(Evaluate, AnyMethodNameAndTimesDisagreeingUnderFrameAssociation) {
  ResultTable result;
  result.path = "r.csv";
  result.rows.push_back(OkRow("orb_slam3", 1, 1, V(5, 0, 0)));
  result.rows.push_back(OkRow("orb_slam3", 2, 2, V(10, 0, 0)));
  result.rows.push_back(OkRow("pnp", 1, 1, V(5, 0, 0)));
  result.rows.push_back(OkRow("pnp", 2, 2 + 3 * 86400.0, V(10, 0, 0)));  // three days later
  const Evaluation eval = Evaluate(result, LTruth(true), LRoute(), EvaluateOptions());
  EXPECT_EQ(eval.association, Association::kFrame);
  ASSERT_EQ(eval.methods.size(), 2u);
  EXPECT_EQ(eval.methods[0].method, "pnp");  // known methods first
  EXPECT_EQ(eval.methods[1].method, "orb_slam3");
  EXPECT_EQ(eval.methods[1].evaluated(), 2);
  std::string warnings;
  for (const std::string& w : eval.warnings) warnings += w + "\n";
  EXPECT_THAT(warnings, ::testing::HasSubstr("method pnp: 1 of 2 rows matched by frame number"));
  EXPECT_THAT(warnings, ::testing::HasSubstr("259200 s, frame 2"));
  EXPECT_THAT(warnings, ::testing::Not(::testing::HasSubstr("method orb_slam3")));
}

TEST(Evaluate, AbsurdTimesGiveShortMessages) {
  // Issue 18 item 12: DBL_MAX seconds were printed with 309 digits.
  ResultTable result;
  result.path = "r.csv";
  result.rows.push_back(OkRow("pnp", kInvalidFrame, 1.7976931348623157e308, V(5, 0, 0)));
  EvaluateOptions by_time;
  by_time.association = Association::kTime;
  const std::string message =
      ErrorOf([&] { Evaluate(result, LTruth(false), LRoute(), by_time); });
  EXPECT_THAT(message, ::testing::HasSubstr("1.797693134862e+308"));
  EXPECT_LT(message.size(), 300u) << message;
}

TEST(Evaluate, FailsWithoutOverlap) {
  ResultTable result;
  result.path = "late.csv";
  result.rows.push_back(OkRow("pnp", kInvalidFrame, 100.0, V(0, 0, 0)));
  ExpectError([&] { Evaluate(result, LTruth(false), LRoute(), EvaluateOptions()); },
              {"late.csv", "no overlap in time", "synthetic_truth"});
  result.rows[0].frame = 40;
  EvaluateOptions by_frame;
  by_frame.association = Association::kFrame;
  ExpectError([&] { Evaluate(result, LTruth(true), LRoute(), by_frame); },
              {"late.csv", "no frame number"});
  ResultTable lost;
  lost.path = "lost.csv";
  lost.rows.push_back(StatusRow("pnp", 1, 1.0, ResultStatus::kLost));
  ExpectError([&] { Evaluate(lost, LTruth(), LRoute(), EvaluateOptions()); },
              {"lost.csv", "no row has status ok"});
  EvaluateOptions bad;
  bad.max_gap_s = -1;
  ExpectError([&] { Evaluate(result, LTruth(), LRoute(), bad); }, {"--max-gap-s"});
}

TEST(Evaluate, GnssBaselineInterpolatesToFrameTimes) {
  const PositionTrack gnss = TrackFromEnu({V(0, 0, 0), V(10, 0, 0)}, {0, 1}, false);
  const std::vector<FrameRecord> frames = {{5, 0.25, ""}, {6, 3.0, ""}};
  const auto rows = GnssBaselineRows(gnss, frames, 1.0);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].method, "gps");
  EXPECT_EQ(rows[0].frame, 5);
  EXPECT_EQ(rows[0].status, ResultStatus::kOk);
  EXPECT_LT((EnuFrame(TestOrigin()).ToEnu(rows[0].position) - V(2.5, 0, 0)).norm(), 1e-6);
  EXPECT_EQ(rows[1].status, ResultStatus::kLost);  // 2 s after the last GNSS sample
}

TEST(EvaluateFiles, EvaluatesResultAndGnssOfADrive) {
  TempDir dir;
  KittiImportOptions import;
  import.raw_drive_dir = WriteMiniKitti(dir / "raw", 5);
  import.out_dir = dir / "drive";
  const Drive drive = ImportKitti(import);  // no GNSS noise: GNSS = ground truth
  // pnp: every frame 1 m north (= ahead: the drive heads north) of its ground truth.
  ResultTable result;
  for (const auto& sample : drive.ground_truth->samples) {
    ResultRow row;
    row.method = "pnp";
    row.frame = sample.frame;
    row.timestamp_s = sample.timestamp_s;
    row.position = EnuFrame(sample.position).ToGeodetic(V(0, 1, 0));
    row.has_position = true;
    result.rows.push_back(row);
  }
  WriteResultCsv(result, dir / "result.csv");

  EvaluateInputs inputs;
  inputs.result_path = dir / "result.csv";
  inputs.truth_path = dir / "drive";
  Evaluation eval = EvaluateFiles(inputs);  // gps added from the truth drive automatically
  ASSERT_EQ(eval.methods.size(), 2u);
  EXPECT_EQ(eval.methods[0].method, "gps");
  EXPECT_EQ(eval.methods[0].evaluated(), 5);
  EXPECT_LT(eval.methods[0].horizontal.max, 1e-6);
  EXPECT_NEAR(eval.methods[1].along_track.bias, 1.0, 1e-6);
  EXPECT_NEAR(eval.methods[1].along_track.std, 0.0, 1e-6);
  EXPECT_NEAR(eval.methods[1].cross_track.mean_abs, 0.0, 1e-6);

  inputs.evaluate.association = Association::kTime;
  eval = EvaluateFiles(inputs);
  EXPECT_LT(eval.methods[0].horizontal.max, 1e-6);
  EXPECT_NEAR(eval.methods[1].along_track.mean_abs, 1.0, 1e-6);

  inputs.auto_gnss = false;
  eval = EvaluateFiles(inputs);
  ASSERT_EQ(eval.methods.size(), 1u);

  // GNSS alone, on the route of a database.
  {
    Database db(dir / "route.sqlite");
    db.SetEnuOrigin(drive.ground_truth->samples[0].position);
    db.WriteRoute({V(0, -10, 0), V(0, 20, 0)});
  }
  EvaluateInputs gnss_only;
  gnss_only.truth_path = dir / "drive";
  gnss_only.gnss_drive_dir = dir / "drive";
  gnss_only.route_db_path = dir / "route.sqlite";
  eval = EvaluateFiles(gnss_only);
  ASSERT_EQ(eval.methods.size(), 1u);
  EXPECT_EQ(eval.methods[0].rows, 5);
  EXPECT_NEAR(eval.route_length_m, 30.0, 1e-9);
  EXPECT_NEAR(eval.truth_s_m[0], 10.0, 1e-6);
  // The drive's frames are 5 ms after the OXTS samples: by frame number the GNSS at frame time
  // is 0.005 s * 1.11213 m / 0.1 s = 0.0556 m ahead of the frame's ground-truth sample.
  EXPECT_EQ(eval.association, Association::kFrame);
  EXPECT_NEAR(eval.methods[0].along_track.bias, 0.0556, 1e-3);

  // --gnss for a result that already has gps rows.
  result.rows.push_back(OkRow("gps", 0, drive.frames[0].timestamp_s, V(0, 0, 0)));
  WriteResultCsv(result, dir / "with_gps.csv");
  inputs.result_path = dir / "with_gps.csv";
  inputs.gnss_drive_dir = dir / "drive";
  ExpectError([&] { EvaluateFiles(inputs); }, {"with_gps.csv", "already has gps rows"});
  gnss_only.route_db_path = dir / "absent.sqlite";
  ExpectError([&] { EvaluateFiles(gnss_only); }, {"absent.sqlite"});
  EvaluateInputs nothing;
  nothing.truth_path = dir / "drive";
  nothing.auto_gnss = false;
  ExpectError([&] { EvaluateFiles(nothing); }, {"nothing to evaluate", "--gnss"});
}

TEST(Evaluate, RotationErrorWhereBothSidesHaveOrientations) {
  // Truth along a road east, camera looking east (x right = south, y down, z forward = east);
  // the last sample 2 km east, where local ENU axes differ from the evaluation's.
  PositionTrack truth = TrackFromEnu({V(0, 0, 0), V(10, 0, 0), V(2000, 0, 0)}, {0, 1, 2}, true);
  Eigen::Matrix3d east_from_cam;
  east_from_cam << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Quaterniond level(east_from_cam);
  for (auto& sample : truth.samples) sample.enu_from_cam = level;
  const Eigen::Quaterniond yawed =
      Eigen::Quaterniond(Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ())) * level;

  ResultTable result;
  result.path = "r.csv";
  result.rows.push_back(OkRow("anchor", 0, 0, V(0.1, 0, 0)));
  result.rows.back().enu_from_cam = yawed;  // 2 degrees off
  result.rows.push_back(OkRow("anchor", 1, 1, V(10, 0, 0)));  // no orientation: not counted
  result.rows.push_back(OkRow("anchor", 2, 2, V(2000, 0.2, 0)));
  result.rows.back().enu_from_cam = level;  // same local orientation: 0 degrees
  result.rows.push_back(OkRow("gps", 0, 0, V(1, 0, 0)));
  const Evaluation eval = Evaluate(result, truth, RouteFromTrack(truth), EvaluateOptions());
  const MethodEvaluation* anchor = eval.Find("anchor");
  ASSERT_NE(anchor, nullptr);
  EXPECT_NEAR(FrameAt(*anchor, 0).rotation_deg, 2.0, 1e-4);
  EXPECT_TRUE(std::isnan(FrameAt(*anchor, 1).rotation_deg));
  EXPECT_NEAR(FrameAt(*anchor, 2).rotation_deg, 0.0, 1e-4);
  EXPECT_EQ(anchor->rotation.count, 2);
  EXPECT_NEAR(anchor->rotation.max, 2.0, 1e-4);
  EXPECT_NEAR(anchor->rotation.mean_abs, 1.0, 1e-4);
  EXPECT_EQ(eval.Find("gps")->rotation.count, 0);
  EXPECT_NE(FormatEvaluationTables(eval).find("Rotation [deg]"), std::string::npos);

  // Without any orientation the table has no rotation section.
  ResultTable plain;
  plain.path = "p.csv";
  plain.rows.push_back(OkRow("gps", 0, 0, V(1, 0, 0)));
  const Evaluation no_rotation = Evaluate(plain, truth, RouteFromTrack(truth), EvaluateOptions());
  EXPECT_EQ(FormatEvaluationTables(no_rotation).find("Rotation [deg]"), std::string::npos);
}

}  // namespace
}  // namespace epiloc
