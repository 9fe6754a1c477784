// The survey chain without RTK and without photographs (issue 17), run with the epiloc binary as a
// user would: a LiDAR map from the survey drive's scans, monocular VO of the query drive (3 m
// GNSS), anchors from the VO structure registered to the map (no photographs, no rendering:
// `epiloc anchor --vo`), piecewise georeferencing (rows with frame numbers, the drive taken from
// the VO file), a route database from that trajectory and the survey drive localized against it.
// On the synthetic street (exact ground truth) and on the shared KITTI drive (OXTS; skipped
// without ../shared/data). Each stage is checked against the ground truth.
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "anchor/anchor_test_util.h"
#include "cli_run_util.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/core/csv.h"
#include "epiloc/eval/evaluate.h"
#include "epiloc/io/pose_files.h"
#include "epiloc/io/result.h"
#include "epiloc/vo/visual_odometry.h"
#include "pipeline_test_util.h"
#include "stella_map_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

void RunEpiloc(const std::string& args) {
  const std::string command = fmt::format("{} {} --quiet", EPILOC_BINARY, args);
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << command;
}

// What the chain reached after the map and the VO (dir/map.ply, dir/vo.tum of `query`).
struct ChainFigures {
  int ok = 0;                // anchors ok
  size_t anchors = 0;        // anchors attempted
  double anchors_max = 0.0;  // largest horizontal error of an ok anchor, metres
  double anchors_rotation_max = 0.0;  // largest rotation error of an ok anchor, degrees
  double piecewise_max = 0.0;
  MethodEvaluation online;  // `survey` localized on the route built from the georeferenced VO
};

// anchor (with `anchor_options`) -> georef piecewise (its rows carry the drive's frame numbers)
// -> build-db from `query` at those positions -> localize `survey` on it -> evaluate.
void AnchorGeorefLocalize(const TempDir& dir,
                          const std::string& query,
                          const std::string& survey,
                          const std::string& anchor_options,
                          ChainFigures* out,
                          bool localize = true) {
  const Drive query_drive = LoadDrive(query);
  const Drive survey_drive = LoadDrive(survey);
  RunEpiloc(fmt::format("anchor --cloud {} --drive {} {} --vo {} --out {}", dir / "map.ply", query,
                        anchor_options, dir / "vo.tum", dir / "anchors.csv"));
  const ResultTable anchors = ReadResultCsv(dir / "anchors.csv");
  for (const ResultRow& r : anchors.rows) out->ok += r.status == ResultStatus::kOk ? 1 : 0;
  out->anchors = anchors.rows.size();
  out->anchors_max = MaxHorizontal(anchors, "anchor", query_drive);
  out->anchors_rotation_max = MaxRotationDeg(anchors, "anchor", query_drive);
  // No --drive: the rows are the VO poses, with the frame numbers of the drive vo.tum names.
  RunEpiloc(fmt::format("georef --vo {} --anchors {} --method piecewise --out {}", dir / "vo.tum",
                        dir / "anchors.csv", dir / "trajectory.csv"));
  const ResultTable trajectory = ReadResultCsv(dir / "trajectory.csv");
  ASSERT_EQ(trajectory.rows.size(), query_drive.frames.size());
  for (size_t i = 0; i < trajectory.rows.size(); ++i) {
    EXPECT_EQ(trajectory.rows[i].frame, query_drive.frames[i].frame);
  }
  out->piecewise_max = MaxHorizontal(trajectory, "piecewise", query_drive);
  if (!localize) return;
  RunEpiloc(fmt::format("build-db --drive {} --positions {} --db {}", query, dir / "trajectory.csv",
                        dir / "route.sqlite"));
  RunEpiloc(fmt::format("localize --db {} --drive {} --out {}", dir / "route.sqlite", survey,
                        dir / "localized.csv"));
  const Evaluation evaluation =
      Evaluate(ReadResultCsv(dir / "localized.csv"), *survey_drive.ground_truth,
               RouteFromDatabase(dir / "route.sqlite"), EvaluateOptions());
  const MethodEvaluation* online = evaluation.Find("online");
  ASSERT_NE(online, nullptr);
  out->online = *online;
}

// The synthetic street's map from its survey drive's LiDAR (dir/map.ply) and its query drive's
// VO (dir/vo.tum, with its points beside it).
void MapAndVo(const TempDir& dir, const std::string& world) {
  RunEpiloc(fmt::format("build-map --drive {} --out {} --origin {:.9f},{:.9f},{:.3f}",
                        world + "/survey", dir / "map.ply", SynthOrigin().lat_deg,
                        SynthOrigin().lon_deg, SynthOrigin().alt_m));
  RunEpiloc(fmt::format("vo --drive {} --out {}", world + "/query", dir / "vo.tum"));
}

// The chain on the synthetic street: its map from the survey's LiDAR, the query's VO, anchors
// every 4th frame with `anchor_options` (besides the prior's), then as AnchorGeorefLocalize; the
// figures printed under `label`. `survey_frames` gets the survey drive's frame count.
ChainFigures SyntheticChain(const std::string& label,
                            const std::string& anchor_options,
                            size_t* survey_frames) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  const std::string query = world + "/query", survey = world + "/survey";
  *survey_frames = LoadDrive(survey).frames.size();
  MapAndVo(dir, world);
  ChainFigures chain;
  AnchorGeorefLocalize(dir, query, survey,
                       "--every 4 --heading-error-deg 5 --camera-height 1.5 " + anchor_options,
                       &chain);
  std::printf(
      "%s anchors %d of %zu ok, horizontal max %.3f m; piecewise georef max %.3f m; survey drive "
      "localized on the VO route: online along-track mean %.3f m over %lld frames\n",
      label.c_str(), chain.ok, chain.anchors, chain.anchors_max, chain.piecewise_max,
      chain.online.along_track.mean_abs, static_cast<long long>(chain.online.evaluated()));
  return chain;
}

TEST(PipelineStructure, MapVoAnchorGeorefDatabaseLocalize) {
  // Without --map-photos and with --vo, anchor registers the VO structure (method structure).
  // This street does not fix the structure along the road: by default every anchor is rejected
  // as weak along it (along_sigma_m of metres, README); --max-along-sigma accepts them here so
  // that the chain runs, and its figures show what such anchors are worth.
  size_t survey_frames = 0;
  const ChainFigures chain =
      SyntheticChain("structure", "--structure vo --max-along-sigma 5", &survey_frames);
  // Targets: <= 0.05 m (anchors, synthetic street), not reached; the figures asserted are those
  // reached with a margin: anchors 9 of 9 ok, max 1.31 m (2.26 m before the drift pass; 3.27 m
  // since the seed follows the road's grade and the seed search tolerates a height error,
  // 2026-11-28: the KLT windows land by chance along the road, and a seed turned by the camera's
  // +-0.4 degree pitch against its track lands them elsewhere; 3.11 m with the tilt held at the
  // coarse levels too); piecewise max the same (it
  // passes through the anchors); the survey drive localized along that route: online along-track
  // mean 0.44 m (1.0 m; the route is as wrong as its anchors).
  EXPECT_GE(chain.ok * 10, static_cast<int>(chain.anchors) * 9);
  EXPECT_LE(chain.anchors_max, 4.0);
  EXPECT_LE(chain.piecewise_max, 4.0);
  // The tracker reports a frame only when its evidence agrees (issue 16); on a route as wrong as
  // these anchors, 17 of 26 frames were (the first waits for a second measurement).
  EXPECT_GE(chain.online.evaluated() * 2, static_cast<int64_t>(survey_frames));
  EXPECT_LE(chain.online.along_track.mean_abs, 6.0);
}

// Median horizontal error of the posed rows of `method` (ok or not) against the drive's truth.
double MedianPosedHorizontal(const ResultTable& table,
                             const std::string& method,
                             const Drive& drive) {
  const EnuFrame enu(drive.ground_truth->samples.front().position);
  std::vector<double> errors;
  for (const ResultRow& r : table.rows) {
    if (r.method != method || !r.has_position) continue;
    const auto truth = drive.ground_truth->Interpolate(r.timestamp_s, drive.max_gap_s);
    if (truth)
      errors.push_back((enu.ToEnu(r.position) - enu.ToEnu(truth->position)).head<2>().norm());
  }
  if (errors.empty()) return INFINITY;
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  return errors[errors.size() / 2];
}

// `anchor --vo` by default (`--structure auto`): on this street the VO's KLT points leave the
// anchors unfixed along the road (median along_sigma_m of metres), so the SIFT structure is tried
// too and kept; its anchors are the SIFT ones (along median 0.055 m here, the KLT points' 0.24 m).
TEST(PipelineStructure, AutoStructureKeepsTheBetterFixedOne) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  const std::string query = world + "/query";
  MapAndVo(dir, world);
  const Drive drive = LoadDrive(query);
  double median[3];
  const char* structures[3] = {"", "--structure vo", "--structure sift"};
  for (int i = 0; i < 3; ++i) {
    RunEpiloc(
        fmt::format("anchor --cloud {} --drive {} --every 4 --heading-error-deg 5 "
                    "--camera-height 1.5 --vo {} {} --out {}",
                    dir / "map.ply", query, dir / "vo.tum", structures[i], dir / "anchors.csv"));
    median[i] = MedianPosedHorizontal(ReadResultCsv(dir / "anchors.csv"), "anchor", drive);
  }
  std::printf("anchors, median horizontal error: auto %.3f m, KLT points %.3f m, SIFT %.3f m\n",
              median[0], median[1], median[2]);
  EXPECT_EQ(median[0], median[2]);
  EXPECT_LT(median[2], median[1]);
}

// Metres per VO unit over the chord from frame `from` to `from + frames` (truth over VO), the VO
// poses matched to the drive's frames by time.
double ChordScale(const Drive& drive,
                  const std::vector<StampedPose>& vo,
                  size_t from,
                  size_t frames) {
  const EnuFrame enu(drive.ground_truth->samples.front().position);
  const auto vo_centre = [&](const FrameRecord& f) {
    for (const StampedPose& p : vo) {
      if (std::abs(p.timestamp_s - f.timestamp_s) < 1e-3) return p.world_from_cam.translation;
    }
    ADD_FAILURE() << "no VO pose at frame " << f.frame;
    return Eigen::Vector3d(Eigen::Vector3d::Zero());
  };
  const auto truth_centre = [&](const FrameRecord& f) {
    const auto s = drive.ground_truth->Interpolate(f.timestamp_s, drive.max_gap_s);
    EXPECT_TRUE(s.has_value()) << f.frame;
    return s ? enu.ToEnu(s->position) : Eigen::Vector3d(Eigen::Vector3d::Zero());
  };
  const FrameRecord& a = drive.frames.at(from);
  const FrameRecord& b = drive.frames.at(from + frames);
  return (truth_centre(b) - truth_centre(a)).norm() / (vo_centre(b) - vo_centre(a)).norm();
}

// The instrument for the shared drive's VO drift (README, "What the drift responds to") and its
// remedy, `calibrate-radial`: a street with two 45 degree turns seen through a KITTI-like camera
// (1242x375, 81 degrees, 10 Hz, grey), its calibration given a radial term k1 = +0.02 the frames
// were not rendered with (a calibration that missed the lens's residual distortion by 7-8 px at
// the edges). The VO then drifts in scale (+10.5 % per 100 m as the anchors measure it; on the
// same street 150 m long +10.1 / +10.2 %, and +9.6 / +10.8 % over 120 m against the truth,
// measured 2026-12-05/06) with the turns right, so only the scale shows the error;
// `calibrate-radial` finds the term at which the anchors see no trend: k1 = +0.0005 in three
// runs (150 m long: -0.0002 / -0.0007 with every 4th / 10th frame anchored; 2026-12-06), and
// the VO it writes keeps its scale against the truth (the first and the last 60-frame chords).
TEST(PipelineStructure, CalibrateRadialFindsTheTermAKittiLikeCameraWasRenderedWith) {
  TempDir dir;
  RunEpiloc(
      fmt::format("synth --out {} --length-m 110 --seed 5 --sharp-curves --query-size 1242x375 "
                  "--query-hfov-deg 81.45 --query-rate-hz 10 --no-distortion --query-grey "
                  "--query-stops none --query-speed-sections none",
                  dir / "world"));
  Drive query = LoadDrive(dir / "world/query");
  ASSERT_GE(query.frames.size(), 140u);
  for (FrameRecord& f : query.frames) f.image = query.ImagePath(f);
  query.camera.distortion[0] = 0.02;
  WriteDrive(query, dir / "miscalibrated");
  const CliRun run = RunCli(fmt::format(
      "calibrate-radial --drive {} --cloud {} --cloud-origin {:.9f},{:.9f},{:.3f} --every 10 "
      "--heading-error-deg 5 --camera-height 1.5 --out {} --vo-out {}",
      dir / "miscalibrated", dir / "world/lidar/map.ply", SynthOrigin().lat_deg,
      SynthOrigin().lon_deg, SynthOrigin().alt_m, dir / "calibrated", dir / "vo.tum"));
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::printf("%s", run.out.c_str());
  const Drive calibrated = LoadDrive(dir / "calibrated");
  EXPECT_NEAR(calibrated.camera.distortion[0], 0.0, 0.004);
  EXPECT_EQ(calibrated.frames.size(), query.frames.size());
  // The runs: the calibration's own term first, its drift plain; the last within the tolerance.
  CsvReader runs(dir / "calibrated/calibration/radial_calibration.csv");
  std::vector<double> trends;
  while (runs.Next()) trends.push_back(runs.GetDouble("trend_percent_per_100m"));
  ASSERT_GE(trends.size(), 2u);
  EXPECT_LE(trends.size(), 4u);
  EXPECT_GT(trends.front(), 6.0);
  EXPECT_LT(std::abs(trends.back()), 2.0);

  const size_t last = query.frames.size() - 61;
  const std::vector<StampedPose> vo = ReadTumPoses(dir / "vo.tum");
  const double change = ChordScale(query, vo, last, 60) / ChordScale(query, vo, 0, 60);
  std::printf("[ figures  ] KITTI-like camera: k1 %+.4f, VO scale change over the drive %+.1f %%\n",
              calibrated.camera.distortion[0], 100.0 * (change - 1.0));
  EXPECT_LT(std::abs(change - 1.0), 0.03);
}

// `anchor --vo` reads the trajectories users have from other SLAM systems, without points: an
// ORB-SLAM-style keyframe trajectory (TUM, every other pose, times from the drive's start, no
// comments, no points file) and KITTI poses (a line per frame). Without points the drive's SIFT
// structure is used; the KITTI poses of every frame give exactly the anchors of `--structure
// sift` on the VO's own file; the frames between keyframes take interpolated poses and are
// anchored too. `--structure vo` without points is a one-line error naming the missing file, and
// so is a trajectory off the drive's clock.
TEST(PipelineStructure, AnchorReadsOtherSlamTrajectoriesWithoutPoints) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  const std::string query = world + "/query";
  MapAndVo(dir, world);
  const Drive drive = LoadDrive(query);
  const std::vector<StampedPose> poses = ReadTumPoses(dir / "vo.tum");
  ASSERT_EQ(poses.size(), drive.frames.size());

  // Keyframes: every other pose, times counted from the drive's first frame.
  std::vector<StampedPose> keyframes;
  for (size_t i = 0; i < poses.size(); i += 2) {
    StampedPose p = poses[i];
    p.timestamp_s -= drive.frames.front().timestamp_s;
    keyframes.push_back(p);
  }
  WriteTumPoses(keyframes, dir / "KeyFrameTrajectory.txt");
  {
    std::ofstream kitti(dir / "poses.txt");
    kitti.precision(17);
    for (const StampedPose& p : poses) {
      const Eigen::Matrix3d r = p.world_from_cam.rotation.toRotationMatrix();
      const Eigen::Vector3d& t = p.world_from_cam.translation;
      for (int row = 0; row < 3; ++row) {
        kitti << (row ? " " : "") << r(row, 0) << ' ' << r(row, 1) << ' ' << r(row, 2) << ' '
              << t(row);
      }
      kitti << '\n';
    }
  }
  const std::string common = fmt::format(
      "anchor --cloud {} --drive {} --every 4 --heading-error-deg 5 --camera-height 1.5",
      dir / "map.ply", query);
  // The summary gives the VO's scale trend from the ok anchors; this VO keeps its scale, so no
  // calibration warning.
  const CliRun sift_run = RunCli(fmt::format("{} --vo {} --structure sift --out {}", common,
                                             dir / "vo.tum", dir / "sift.csv"));
  ASSERT_EQ(sift_run.exit_code, 0) << sift_run.err;
  EXPECT_NE(sift_run.out.find("VO scale from the ok anchors"), std::string::npos) << sift_run.out;
  EXPECT_EQ(sift_run.err.find("the VO's scale changes"), std::string::npos) << sift_run.err;
  RunEpiloc(fmt::format("{} --vo {} --vo-format kitti --out {}", common, dir / "poses.txt",
                        dir / "kitti.csv"));
  RunEpiloc(fmt::format("{} --vo {} --relative-times --out {}", common,
                        dir / "KeyFrameTrajectory.txt", dir / "keyframes.csv"));
  const ResultTable sift = ReadResultCsv(dir / "sift.csv");
  const ResultTable kitti = ReadResultCsv(dir / "kitti.csv");
  const ResultTable keyframes_anchored = ReadResultCsv(dir / "keyframes.csv");
  ASSERT_EQ(kitti.rows.size(), sift.rows.size());
  ASSERT_EQ(keyframes_anchored.rows.size(), sift.rows.size());
  int posed = 0;
  for (size_t i = 0; i < sift.rows.size(); ++i) {
    EXPECT_EQ(kitti.rows[i].status, sift.rows[i].status) << i;
    EXPECT_EQ(kitti.rows[i].has_position, sift.rows[i].has_position) << i;
    if (kitti.rows[i].has_position && sift.rows[i].has_position) {
      const EnuFrame enu(sift.rows[i].position);
      EXPECT_LT(enu.ToEnu(kitti.rows[i].position).norm(), 1e-3) << i;
    }
    posed += keyframes_anchored.rows[i].has_position ? 1 : 0;
  }
  const double median_sift = MedianPosedHorizontal(sift, "anchor", drive);
  const double median_keyframes = MedianPosedHorizontal(keyframes_anchored, "anchor", drive);
  std::printf(
      "anchors, median horizontal error: SIFT structure on the VO's file %.3f m; keyframes "
      "(every other pose) %.3f m, %d of %zu posed\n",
      median_sift, median_keyframes, posed, keyframes_anchored.rows.size());
  // Every anchor frame lies between two keyframes (or on one) but the last, beyond the last one.
  EXPECT_GE(posed + 1, static_cast<int>(keyframes_anchored.rows.size()));
  EXPECT_LE(median_keyframes, 2.0 * median_sift + 0.05);

  const CliRun vo_points =
      RunCli(fmt::format("{} --vo {} --relative-times --structure vo --out {} -q", common,
                         dir / "KeyFrameTrajectory.txt", dir / "none.csv"));
  EXPECT_NE(vo_points.exit_code, 0);
  EXPECT_EQ(NumLines(vo_points.err), 1) << vo_points.err;
  EXPECT_NE(vo_points.err.find("KeyFrameTrajectory.points.csv"), std::string::npos)
      << vo_points.err;
  // Times from the sequence's start without --relative-times: no pose on the drive's clock.
  const CliRun clock = RunCli(fmt::format("{} --vo {} --out {} -q", common,
                                          dir / "KeyFrameTrajectory.txt", dir / "none.csv"));
  EXPECT_NE(clock.exit_code, 0);
  EXPECT_EQ(NumLines(clock.err), 1) << clock.err;
  EXPECT_NE(clock.err.find("--relative-times"), std::string::npos) << clock.err;
}

// stella_vslam's map database (map.msg) as `--vo`: its keyframes are the trajectory and its
// landmarks, with the keyframes that observe them, the structure. The tests' VO written as such a
// map (every pose a keyframe; each point observed from its first and last keyframe and as many
// between as it had observations) gives the anchors of the VO's own file and points exactly.
TEST(PipelineStructure, AnchorReadsAStellaVslamMap) {
  const std::string world = SharedSyntheticWorld();
  TempDir dir;
  const std::string query = world + "/query";
  MapAndVo(dir, world);
  const std::vector<StampedPose> poses = ReadTumPoses(dir / "vo.tum");
  const std::vector<VoPoint> points = ReadVoPoints(VoPointsPath(dir / "vo.tum"));
  ASSERT_GT(points.size(), 100u);
  const Drive drive = LoadDrive(query);
  ASSERT_EQ(poses.size(), drive.frames.size());  // every frame posed, in order
  std::vector<TestStellaKeyframe> keyframes;
  std::map<frame_t, size_t> keyframe_of;
  for (size_t i = 0; i < poses.size(); ++i) {
    keyframes.push_back(
        {static_cast<int64_t>(i), poses[i].timestamp_s, poses[i].world_from_cam, {}});
    keyframe_of[drive.frames[i].frame] = i;
  }
  std::vector<TestStellaLandmark> landmarks;
  for (size_t id = 0; id < points.size(); ++id) {
    const VoPoint& p = points[id];
    landmarks.push_back({static_cast<int64_t>(id), p.point_in_world});
    const size_t first = keyframe_of.at(p.first_frame), last = keyframe_of.at(p.last_frame);
    std::vector<size_t> seen = {first, last};
    for (size_t k = first + 1; k < last && static_cast<int>(seen.size()) < p.observations; ++k) {
      seen.push_back(k);
    }
    ASSERT_EQ(static_cast<int>(seen.size()), p.observations) << id;
    for (const size_t k : seen) {
      keyframes[k].landmark_ids.push_back(-1);  // a keypoint without a landmark
      keyframes[k].landmark_ids.push_back(static_cast<int64_t>(id));
    }
  }
  WriteMessagePack(StellaMapJson(keyframes, landmarks), dir / "map.msg");
  const std::string common = fmt::format(
      "anchor --cloud {} --drive {} --every 4 --heading-error-deg 5 --camera-height 1.5 "
      "--structure vo",
      dir / "map.ply", query);
  RunEpiloc(fmt::format("{} --vo {} --out {}", common, dir / "vo.tum", dir / "vo.csv"));
  RunEpiloc(fmt::format("{} --vo {} --out {}", common, dir / "map.msg", dir / "stella.csv"));
  const ResultTable vo = ReadResultCsv(dir / "vo.csv");
  const ResultTable stella = ReadResultCsv(dir / "stella.csv");
  ASSERT_EQ(stella.rows.size(), vo.rows.size());
  int posed = 0;
  for (size_t i = 0; i < vo.rows.size(); ++i) {
    EXPECT_EQ(stella.rows[i].status, vo.rows[i].status) << i;
    ASSERT_EQ(stella.rows[i].has_position, vo.rows[i].has_position) << i;
    if (!vo.rows[i].has_position) continue;
    ++posed;
    const EnuFrame enu(vo.rows[i].position);
    EXPECT_LT(enu.ToEnu(stella.rows[i].position).norm(), 1e-3) << i;
  }
  EXPECT_GE(posed * 2, static_cast<int>(vo.rows.size()));
  // A map saved in stella's SQLite format is named as such.
  WriteText(dir / "map.db", std::string("SQLite format 3") + '\0' + "tables");
  const CliRun sqlite = RunCli(fmt::format("{} --vo {} --vo-format stella_map --out {} -q", common,
                                           dir / "map.db", dir / "none.csv"));
  EXPECT_NE(sqlite.exit_code, 0);
  EXPECT_EQ(NumLines(sqlite.err), 1) << sqlite.err;
  EXPECT_NE(sqlite.err.find("SQLite map database"), std::string::npos) << sqlite.err;
}

// The same chain with the query's SIFT features triangulated along its VO poses as the structure
// (`anchor --structure sift`).
TEST(PipelineStructure, SiftStructureChainOnTheSyntheticStreet) {
  size_t survey_frames = 0;
  const ChainFigures chain =
      SyntheticChain("SIFT structure", "--structure sift --max-along-sigma 5", &survey_frames);
  // Measured: anchors max 0.34 m (KLT points: 1.31 m), piecewise georef max 0.34 m (1.31), the
  // survey drive on that route online along-track mean 0.067 m over 17 frames (0.44 m); before
  // the anchors' drift pass 0.66 m, 0.66 m and 0.15 m. Still short of the 0.05 m target;
  // asserted with a margin.
  EXPECT_GE(chain.ok * 10, static_cast<int>(chain.anchors) * 9);
  EXPECT_LE(chain.anchors_max, 0.6);
  EXPECT_LE(chain.piecewise_max, 0.6);
  EXPECT_GE(chain.online.evaluated() * 2, static_cast<int64_t>(survey_frames));
  EXPECT_LE(chain.online.along_track.mean_abs, 0.15);
}

// A synthetic survey with a 16-beam scanner (synth --lidar-scan-files writes its scans and their
// exact poses): lidar-track registers every pair and finds the track it was given, within what
// 16 beams fix (the exact track corrected by at most 0.09 m over 80 m, measured 2026-11-28; 9 mm
// with 64 beams). The same track shrunk by 3 % and tilted 0.5 deg (a throwaway script) came back
// within 0.088 m. synth writes the map's sidecar (its ENU origin, points and scans) as build-map
// does.
TEST(PipelineStructure, SynthScanFilesFeedLidarTrackAndCarryTheMapFrame) {
  TempDir dir;
  RunEpiloc(
      fmt::format("synth --length-m 80 --seed 4 --lidar-rings 16 --lidar-spacing 5 --lidar-fov 360 "
                  "--lidar-scan-files --out {}",
                  dir / "world"));
  const Drive survey = LoadDrive(dir / "world/survey");
  ASSERT_GE(survey.lidar.size(), 10u);
  // The map's frame travels with it (anchor and render need no --cloud-origin).
  const std::optional<MapSidecar> sidecar = FindMapSidecar(dir / "world/lidar/map.ply");
  ASSERT_TRUE(sidecar.has_value());
  EXPECT_DOUBLE_EQ(sidecar->enu_origin.lat_deg, SynthOrigin().lat_deg);
  EXPECT_DOUBLE_EQ(sidecar->enu_origin.lon_deg, SynthOrigin().lon_deg);
  EXPECT_DOUBLE_EQ(sidecar->enu_origin.alt_m, SynthOrigin().alt_m);
  EXPECT_EQ(sidecar->num_points,
            static_cast<int64_t>(ReadPointCloud(dir / "world/lidar/map.ply").size()));
  EXPECT_EQ(sidecar->num_scans, static_cast<int64_t>(survey.lidar.size()));
  RunEpiloc(fmt::format("lidar-track --drive {} --steps {} --out {}", dir / "world/survey",
                        dir / "steps.csv", dir / "corrected"));
  CsvReader steps(dir / "steps.csv");
  size_t pairs = 0;
  double max_correction = 0.0;
  while (steps.Next()) {
    ++pairs;
    EXPECT_EQ(steps.GetInt("registered"), 1) << steps.where();
    max_correction = std::max(max_correction, std::hypot(steps.GetDouble("correction_e_m"),
                                                         steps.GetDouble("correction_n_m"),
                                                         steps.GetDouble("correction_u_m")));
  }
  EXPECT_EQ(pairs, survey.lidar.size() - 1);
  EXPECT_LT(max_correction, 0.15);
  const Drive corrected = LoadDrive(dir / "corrected");
  EXPECT_EQ(corrected.lidar.size(), survey.lidar.size());
  EXPECT_EQ(corrected.ground_truth->samples.size(), survey.ground_truth->samples.size());
}

// The same chain on the shared KITTI drive, issue 17's development scenario: the map from camera
// 0's LiDAR scans (every 5th scan in the shared copy, intensity only), camera 1 with 3 m GNSS
// noise and a prior heading up to 5 degrees off, its camera's radial residual estimated from the
// map (calibrate-radial, which writes the VO), anchored every 10th frame from its own VO
// structure; camera 0's drive localized on the route built from camera 1's georeferenced VO.
// Both drives first put on the path their LiDAR agrees with (lidar-track), so that the map and
// the ground truth agree with each other. (The anchors without the radial term: the shared
// drive's structure_anchor_kitti_test.cc.)
TEST(PipelineStructure, KittiMapVoAnchorGeorefDatabaseLocalize) {
  namespace fs = std::filesystem;
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  TempDir dir;
  const std::string oxts0 = dir / "oxts0", oxts1 = dir / "oxts1";
  RunEpiloc(fmt::format("import-kitti --raw {} --camera 0 --out {}", raw.string(), oxts0));
  RunEpiloc(
      fmt::format("import-kitti --raw {} --camera 1 --gps-noise 3 --out {}", raw.string(), oxts1));
  // The drives with their scans and ground truth on the path the LiDAR agrees with (README: the
  // OXTS track steps 3.7 % short of its scans and travels 0.43 deg flatter; the GNSS is kept).
  const std::string cam0 = dir / "cam0", cam1 = dir / "cam1";
  RunEpiloc(
      fmt::format("lidar-track --drive {} --out {} --steps {}", oxts0, cam0, dir / "steps.csv"));
  RunEpiloc(fmt::format("lidar-track --drive {} --out {}", oxts1, cam1));
  {
    std::ifstream steps(dir / "steps.csv");
    int lines = 0;
    for (std::string line; std::getline(steps, line);) ++lines;
    EXPECT_EQ(lines, 31);  // the header and the 30 pairs of the 31 scans
  }
  // The check prints the stretch the scans agree with (about 1.00 now, 1.04 on the OXTS track).
  RunEpiloc(
      fmt::format("build-map --drive {} --out {} --check-track-scale", cam0, dir / "map.ply"));
  // Camera 1's residual radial distortion estimated from the map first (calibrate-radial, k1;
  // its VO written for the anchors): the rectified images' residual costs the VO 29 % of its
  // scale per 100 m (README, "The radial term from the map"). The anchors' reliability as it
  // comes (the ok ones only reach georef).
  const std::string calibrated = dir / "cam1_radial";
  const CliRun run = RunCli(fmt::format(
      "calibrate-radial --drive {} --cloud {} --every 10 --heading-error-deg 5 --out {} "
      "--vo-out {}",
      cam1, dir / "map.ply", calibrated, dir / "vo.tum"));
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::printf("%s", run.out.c_str());
  const double k1 = LoadDrive(calibrated).camera.distortion[0];
  EXPECT_GT(k1, 0.012);
  EXPECT_LT(k1, 0.03);
  CsvReader runs(calibrated + "/calibration/radial_calibration.csv");
  ASSERT_TRUE(runs.Next());
  EXPECT_LT(runs.GetDouble("trend_percent_per_100m"), -15.0);  // the VO as calibrated
  ChainFigures chain;
  AnchorGeorefLocalize(dir, calibrated, cam0, "--every 10 --heading-error-deg 5", &chain);
  const ErrorStatistics& along = chain.online.along_track;
  std::printf(
      "with k1 %+.4f from the map: KITTI structure anchors %d of %zu ok, horizontal max %.3f m, "
      "rotation max %.2f deg; piecewise georef max %.3f m; camera 0 localized on the VO route: "
      "online along-track mean %.3f m, max %.3f m over %lld frames\n",
      k1, chain.ok, chain.anchors, chain.anchors_max, chain.anchors_rotation_max,
      chain.piecewise_max, along.mean_abs, std::max(-along.min, along.max),
      static_cast<long long>(chain.online.evaluated()));
  // Targets (issue 17): anchors <= 0.5 m, piecewise georef <= 0.3 m. Measured with every anchor
  // accepted (--max-along-sigma 5), without the radial term: on the OXTS drives (map, truth and
  // GNSS from the OXTS track as imported) 16 of 16 ok, max 0.93 m, piecewise 0.93 m, camera 0
  // online along-track mean 0.44 m, max 0.91 m (2026-11-28); on the drives lidar-track
  // corrects, max 0.405 m, piecewise 0.422 m, camera 0 online mean 0.077 m. With the
  // reliability as it comes (2026-11-28, fourth session): 9 of 16 ok, within 0.196 m; piecewise
  // max 0.228 m; camera 0 online along-track mean 0.036 m, max 0.126 m over 153 frames; then
  // 10, 12, 13 of 16 ok with the graded along-road test, the neighbours' check and the drift from
  // the neighbours' scales (online mean 0.038-0.042 m); with the ok claim at the profile's
  // resolution, the consensus placement and the 80 m rotation consensus (2026-12-06): 16 of 16
  // ok within 0.205 m, georef 0.205 m, online mean 0.035 m, max 0.178 m. With the truth at the
  // trigger times (the import's default since 2026-12-06): 16 of 16 ok within 0.216 m, rotation
  // max 0.49 deg, georef 0.232 m, camera 0 online mean 0.078 m, max 0.208 m (the VO's radial
  // drift no longer offset by the truth's lag). With calibrate-radial (the same day): k1
  // +0.0190, 16 of 16 ok within 0.176 m, rotation max 0.40 deg, georef 0.176 m, camera 0 online
  // mean 0.021 m, max 0.098 m over 153 frames. The targets asserted, the positions with margins.
  EXPECT_GE(chain.ok * 10, static_cast<int>(chain.anchors) * 9);
  EXPECT_LE(chain.anchors_max, 0.3);
  EXPECT_LE(chain.anchors_rotation_max, 0.5);
  EXPECT_LE(chain.piecewise_max, 0.3);
  EXPECT_GE(chain.online.evaluated() * 10, static_cast<int64_t>(LoadDrive(cam0).frames.size()) * 9);
  EXPECT_LE(along.mean_abs, 0.06);
}

}  // namespace
}  // namespace epiloc
