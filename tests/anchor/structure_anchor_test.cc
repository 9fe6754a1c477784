// Anchoring from structure on the synthetic street: the query drive's own VO points registered
// to the simulated LiDAR map (no photographs, no rendering), against the exact ground truth.
#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/anchor/structure_sift.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <gtest/gtest.h>

#include "anchor_test_util.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/core/angles.h"
#include "test_util.h"

namespace epiloc {
namespace {

struct Errors {
  int ok = 0;
  int total = 0;
  std::vector<double> horizontal_m;
  double max_horizontal_m = 0.0;
  double max_3d_m = 0.0;
  double max_rotation_deg = 0.0;
  double seconds = 0.0;
  // Of every frame with a pose, ok or rejected: the error along the road (the camera's levelled
  // viewing direction) beside the along-track sigma the anchor reports, across it, rotation.
  int posed = 0;
  std::vector<double> along_m;
  std::vector<double> along_sigma_m;
  std::vector<double> posed_horizontal_m;
  std::vector<double> posed_rotation_deg;
  double max_across_m = 0.0;
  double max_rotation_posed_deg = 0.0;
};

Errors Compare(const AnchorDriveResult& result, const Drive& drive, const EnuFrame& enu) {
  Errors e;
  for (const AnchorResult& a : result.frames) {
    ++e.total;
    e.seconds += a.seconds;
    if (a.status != AnchorStatus::kOk) {
      std::printf("frame %lld: %s %s\n", static_cast<long long>(a.frame),
                  AnchorStatusName(a.status).c_str(), a.message.c_str());
    }
    if (!a.has_pose) continue;
    const auto truth = TrueMapFromCam(drive, a.timestamp_s, enu);
    EXPECT_TRUE(truth.has_value());
    if (!truth) continue;
    const Eigen::Vector3d d = a.map_from_cam.translation - truth->translation;
    Eigen::Vector3d forward = truth->rotation * Eigen::Vector3d::UnitZ();
    forward.z() = 0.0;
    forward.normalize();
    const Eigen::Vector3d left = Eigen::Vector3d::UnitZ().cross(forward);
    const double rotation_deg = RotationDifferenceDeg(a.map_from_cam.rotation, truth->rotation);
    ++e.posed;
    e.along_m.push_back(d.dot(forward));
    e.along_sigma_m.push_back(a.along_sigma_m);
    e.posed_horizontal_m.push_back(d.head<2>().norm());
    e.posed_rotation_deg.push_back(rotation_deg);
    e.max_across_m = std::max(e.max_across_m, std::abs(d.dot(left)));
    e.max_rotation_posed_deg = std::max(e.max_rotation_posed_deg, rotation_deg);
    // The error rotation in the map: its vertical part a turn, the rest a tilt.
    const Eigen::AngleAxisd turn(a.map_from_cam.rotation * truth->rotation.conjugate());
    std::printf(
        "frame %3lld %s: along %+.3f m (sigma %.3f m), across %+.3f m, up %+.3f m, %.3f deg (yaw "
        "%+.3f, tilt %.3f)\n",
        static_cast<long long>(a.frame), AnchorStatusName(a.status).c_str(), d.dot(forward),
        a.along_sigma_m, d.dot(left), d.z(), rotation_deg,
        turn.angle() * turn.axis().z() / kDegToRad,
        turn.angle() * turn.axis().head<2>().norm() / kDegToRad);
    if (a.status != AnchorStatus::kOk) continue;
    ++e.ok;
    e.max_horizontal_m = std::max(e.max_horizontal_m, d.head<2>().norm());
    e.horizontal_m.push_back(d.head<2>().norm());
    e.max_3d_m = std::max(e.max_3d_m, d.norm());
    e.max_rotation_deg = std::max(e.max_rotation_deg,
                                  RotationDifferenceDeg(a.map_from_cam.rotation, truth->rotation));
    std::printf(
        "frame %3lld ok: %.3f m horizontal, %.3f deg, scale %.4f (seed %.4f), %d of %d points "
        "(share %.2f), residual %.3f m, along %.3f / %.4f m, %.2f s\n",
        static_cast<long long>(a.frame), d.head<2>().norm(),
        RotationDifferenceDeg(a.map_from_cam.rotation, truth->rotation), a.scale_m_per_unit,
        a.seed_scale_m_per_unit, a.num_inliers, a.structure_points, a.inlier_share, a.residual_m,
        a.along_information, a.along_sigma_m, a.seconds);
  }
  if (e.total > 0) e.seconds /= e.total;
  return e;
}

// The synthetic query anchored every 4th frame against the world's LiDAR map, its prior heading
// up to 5 degrees off.
AnchorInputs QueryInputs(const std::string& world) {
  AnchorInputs inputs;
  inputs.cloud_path = world + "/lidar/map.ply";
  inputs.map_origin = SynthOrigin();
  inputs.drive_dir = world + "/query";
  inputs.every = 4;
  return inputs;
}

StructureAnchorOptions QueryOptions() {
  StructureAnchorOptions options;
  options.prior.camera_height_m = 1.5;  // DriveOptions::Query()
  options.heading_error_deg = 5.0;
  return options;
}

TEST(StructureAnchor, AnchorsSyntheticQueryFromItsOwnStructure) {
  const std::string world = SharedSyntheticWorld();
  const Drive query = LoadDrive(world + "/query");
  const VoStructure vo = VoStructure::FromResult(RunVisualOdometry(query, VoOptions()));
  ASSERT_GT(vo.points.size(), 500u);
  const AnchorInputs inputs = QueryInputs(world);
  const StructureAnchorOptions options = QueryOptions();
  int64_t progress_calls = 0;
  const AnchorDriveResult result =
      AnchorDriveByStructure(inputs, vo, options, [&](int64_t, int64_t) { ++progress_calls; });
  EXPECT_EQ(progress_calls, static_cast<int64_t>(result.frames.size()));
  const Errors e = Compare(result, query, EnuFrame(SynthOrigin()));
  std::printf(
      "synthetic street: %d of %d ok, horizontal max %.3f m, 3-D max %.3f m, rotation "
      "max %.3f deg, %.2f s per anchor\n",
      e.ok, e.total, e.max_horizontal_m, e.max_3d_m, e.max_rotation_deg, e.seconds);
  ASSERT_GE(e.total, 5);
  // Targets (issue 17): <= 0.05 m and 0.1 degrees: not reached with the VO's KLT points. Their
  // noise (median 0.22 m off the world's surfaces) leaves the count of points on the map's
  // surfaces flat along the road within its counting noise (README), so each window lands by
  // chance; the consensus of neighbouring anchors (StructureAnchorOptions::consensus_radius_m)
  // pulls those off the majority back (0.2-2.3 m off before it; 0.72 m at most with it, 1.33 m
  // with the drift pass, the last anchor, sigma 3.75 m). The anchors say so: along_sigma_m from
  // that profile, and all are rejected as weak along the road. (2026-11-28: with the seed
  // turned to the road's grade, on this flat street by the camera's +-0.4 degree pitch against
  // its track, one anchor landed 3.05 m off claiming 1.05 m; with the tilt held at the coarse
  // levels too, the worst is 2.04 m off claiming 2.55 m.)
  EXPECT_EQ(e.posed, e.total);
  for (size_t i = 0; i < e.along_m.size(); ++i) {
    EXPECT_LE(std::abs(e.along_m[i]), 2.0 * e.along_sigma_m[i] + 0.1) << "posed anchor " << i;
  }
  // An anchor called ok is right (none is here); across the road and in rotation the structure
  // does place the camera (reached: 0.38 m, 0.94 deg, tied to where it lands along the road).
  if (e.ok > 0) {
    EXPECT_LE(e.max_horizontal_m, 0.3);
  }
  EXPECT_LE(e.max_across_m, 0.6);
  EXPECT_LE(e.max_rotation_posed_deg, 1.3);

  // The placing registration's parallax floor (StructureAnchorOptions::min_parallax_deg): the
  // default leaves points out of it (the structure it reports is smaller somewhere); a floor no
  // point meets leaves the window every point rather than no registration: the anchors are
  // those without a floor.
  StructureAnchorOptions no_floor = options;
  no_floor.min_parallax_deg = 0.0;
  StructureAnchorOptions unmet_floor = options;
  unmet_floor.min_parallax_deg = 89.0;
  const AnchorDriveResult without = AnchorDriveByStructure(inputs, vo, no_floor);
  const AnchorDriveResult unmet = AnchorDriveByStructure(inputs, vo, unmet_floor);
  ASSERT_EQ(without.frames.size(), result.frames.size());
  ASSERT_EQ(unmet.frames.size(), result.frames.size());
  int fewer = 0;
  for (size_t k = 0; k < result.frames.size(); ++k) {
    const AnchorResult& a = without.frames[k];
    const AnchorResult& b = unmet.frames[k];
    EXPECT_EQ(a.status, b.status) << a.frame;
    EXPECT_EQ(a.structure_points, b.structure_points) << a.frame;
    EXPECT_LT((a.map_from_cam.translation - b.map_from_cam.translation).norm(), 1e-9) << a.frame;
    fewer += result.frames[k].structure_points < a.structure_points ? 1 : 0;
  }
  EXPECT_GT(fewer, 0);
}

double Median(std::vector<double> v) {
  if (v.empty()) return INFINITY;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double Max(const std::vector<double>& v) {
  return v.empty() ? INFINITY : *std::max_element(v.begin(), v.end());
}

// One line: the ok anchors' worst, then every posed anchor's median and worst.
void PrintPosed(const char* label, const Errors& e) {
  std::printf(
      "%s: %d of %d ok (max %.3f m, %.3f deg); every posed anchor: horizontal median %.3f max "
      "%.3f m, rotation median %.3f max %.3f deg, %.2f s per anchor\n",
      label, e.ok, e.total, e.max_horizontal_m, e.max_rotation_deg, Median(e.posed_horizontal_m),
      Max(e.posed_horizontal_m), Median(e.posed_rotation_deg), Max(e.posed_rotation_deg),
      e.seconds);
}

// The drive's own SIFT features triangulated along its VO poses (structure_sift.h) in place of the
// VO's KLT points (`epiloc anchor --structure sift`): the map places them better across the road
// and in rotation (README "Anchoring from structure").
TEST(StructureAnchor, SiftStructureAlongTheVoPosesPlacesTheSyntheticQuery) {
  const std::string world = SharedSyntheticWorld();
  const Drive query = LoadDrive(world + "/query");
  const VoStructure klt = VoStructure::FromResult(RunVisualOdometry(query, VoOptions()));
  BuildDbOptions build;
  build.num_threads = 2;
  SiftStructureSummary summary;
  const VoStructure sift = TriangulateAlongVo(world + "/query", klt, build, &summary);
  std::printf("SIFT structure: %lld points (mean track %.1f frames) from %d frames, %.1f s\n",
              static_cast<long long>(summary.points), summary.mean_track_length, summary.frames,
              summary.seconds);
  EXPECT_EQ(summary.segments, 1);
  EXPECT_GT(summary.points, 2 * static_cast<int64_t>(klt.points.size()));
  ASSERT_EQ(sift.poses.size(), klt.poses.size());

  const AnchorInputs inputs = QueryInputs(world);
  const StructureAnchorOptions options = QueryOptions();
  const AnchorDriveResult sift_result = AnchorDriveByStructure(inputs, sift, options);
  const Errors with_sift = Compare(sift_result, query, EnuFrame(SynthOrigin()));
  // The fits' exchange or the consensus pass re-registered some anchors (those that landed a
  // facade period off their neighbours); without them, none is.
  const auto reregistered = [](const AnchorDriveResult& r) {
    int n = 0;
    for (const AnchorResult& a : r.frames) {
      n += a.message.find("consensus") != std::string::npos ||
           a.message.find("registered from frame") != std::string::npos;
    }
    return n;
  };
  EXPECT_GE(reregistered(sift_result), 1);
  StructureAnchorOptions no_consensus = options;
  no_consensus.consensus_radius_m = 0.0;
  no_consensus.exchange_rounds = 0;
  const AnchorDriveResult alone = AnchorDriveByStructure(inputs, sift, no_consensus);
  EXPECT_EQ(reregistered(alone), 0);
  std::vector<double> alone_along;
  for (double a : Compare(alone, query, EnuFrame(SynthOrigin())).along_m) {
    alone_along.push_back(std::abs(a));
  }
  const AnchorDriveResult klt_result = AnchorDriveByStructure(inputs, klt, options);
  const Errors with_klt = Compare(klt_result, query, EnuFrame(SynthOrigin()));

  // `auto` (AnchorDriveByStructureAuto): the KLT points' first pass leaves the anchors unfixed
  // along the road, so the SIFT structure is asked for (once), fixes them better and gets the
  // passes: the very anchors AnchorDriveByStructure gives with it. Where the first structure
  // fixes them (a gate of 100 m), the alternative is not asked for.
  const auto same_poses = [](const AnchorDriveResult& a, const AnchorDriveResult& b) {
    if (a.frames.size() != b.frames.size()) return false;
    for (size_t i = 0; i < a.frames.size(); ++i) {
      if (a.frames[i].has_pose != b.frames[i].has_pose ||
          a.frames[i].status != b.frames[i].status ||
          (a.frames[i].has_pose &&
           (a.frames[i].map_from_cam.translation - b.frames[i].map_from_cam.translation).norm() >
               1e-12)) {
        return false;
      }
    }
    return true;
  };
  int asked = 0;
  const auto ask = [&] {
    ++asked;
    return sift;
  };
  StructureChoice choice;
  const AnchorDriveResult by_auto =
      AnchorDriveByStructureAuto(inputs, klt, ask, options, nullptr, &choice);
  EXPECT_EQ(asked, 1);
  EXPECT_TRUE(choice.alternative_tried);
  EXPECT_TRUE(choice.alternative_kept);
  EXPECT_GT(choice.first_sigma_m, options.max_along_sigma_m);
  EXPECT_LT(choice.alternative_sigma_m, choice.first_sigma_m);
  EXPECT_TRUE(same_poses(by_auto, sift_result));
  StructureAnchorOptions lenient = options;
  lenient.max_along_sigma_m = 100.0;
  const AnchorDriveResult klt_fixes = AnchorDriveByStructureAuto(inputs, klt, ask, lenient);
  EXPECT_EQ(asked, 1);
  EXPECT_TRUE(same_poses(klt_fixes, AnchorDriveByStructure(inputs, klt, lenient)));
  // Where the first structure fixes its first pass but leaves fewer than auto_min_ok_share of the
  // anchors ok in the end, the alternative's finished run too, and the one with more ok anchors
  // is kept (ties: the first). Here the SIFT structure given first, with the reliability limit
  // along the road just above 0.3 m (its first pass's median sigma, so it counts as fixed: a
  // median at the limit would not; the profile's sigmas come in steps of 0.15 m, so 0.31 m lets
  // the anchors 0.3 m does) and every anchor asked to be ok.
  StructureAnchorOptions relaxed = options;
  relaxed.max_along_sigma_m = 0.31;
  relaxed.auto_min_ok_share = 1.0;
  const auto count_ok = [](const AnchorDriveResult& r) {
    return static_cast<int>(std::count_if(r.frames.begin(), r.frames.end(), [](const auto& a) {
      return a.status == AnchorStatus::kOk;
    }));
  };
  const AnchorDriveResult sift_relaxed = AnchorDriveByStructure(inputs, sift, relaxed);
  const AnchorDriveResult klt_relaxed = AnchorDriveByStructure(inputs, klt, relaxed);
  const int sift_ok = count_ok(sift_relaxed);
  const int klt_ok = count_ok(klt_relaxed);
  std::printf("ok anchors with a 0.31 m limit: SIFT %d, KLT %d of %zu\n", sift_ok, klt_ok,
              sift_relaxed.frames.size());
  ASSERT_LT(sift_ok, static_cast<int>(sift_relaxed.frames.size()));
  int asked_klt = 0;
  const auto ask_klt = [&] {
    ++asked_klt;
    return klt;
  };
  StructureChoice by_ok;
  const AnchorDriveResult sift_first =
      AnchorDriveByStructureAuto(inputs, sift, ask_klt, relaxed, nullptr, &by_ok);
  EXPECT_EQ(asked_klt, 1);
  EXPECT_LE(by_ok.first_sigma_m, relaxed.max_along_sigma_m);
  EXPECT_TRUE(by_ok.decided_by_ok);
  EXPECT_EQ(by_ok.first_ok, sift_ok);
  EXPECT_EQ(by_ok.alternative_ok, klt_ok);
  EXPECT_EQ(by_ok.alternative_kept, klt_ok > sift_ok);
  EXPECT_TRUE(same_poses(sift_first, klt_ok > sift_ok ? klt_relaxed : sift_relaxed));

  std::vector<double> sift_along, klt_along;
  for (double a : with_sift.along_m) sift_along.push_back(std::abs(a));
  for (double a : with_klt.along_m) klt_along.push_back(std::abs(a));
  std::printf(
      "along-track median: SIFT %.3f m, KLT %.3f m; across max %.3f / %.3f m; rotation "
      "max %.3f / %.3f deg\n",
      Median(sift_along), Median(klt_along), with_sift.max_across_m, with_klt.max_across_m,
      with_sift.max_rotation_posed_deg, with_klt.max_rotation_posed_deg);
  ASSERT_EQ(with_sift.posed, with_sift.total);
  // Measured on this world (9 anchors, a 3 Hz query), with the drift pass and the consensus
  // pass: along the road median 0.055 m, max 0.34 m (KLT 0.24 / 1.33 m; before the drift pass
  // SIFT 0.15 / 0.65 m); across 0.05 m at most (KLT 0.31 m); rotation 0.17 degrees at most (KLT
  // 0.74). Without the consensus pass anchors land 2-7 m off. On a 15 Hz query of the same
  // street (165 frames, 42 anchors; README) the median is 0.035 m against 3.0 m. Anchors stay
  // rejected: the along-track profile still calls them weak along the road.
  std::vector<double> sift_abs = sift_along;
  std::sort(sift_abs.begin(), sift_abs.end());
  EXPECT_LE(Median(sift_along), 0.12);
  EXPECT_LE(sift_abs.back(), *std::max_element(alone_along.begin(), alone_along.end()));
  EXPECT_LT(Median(sift_along), Median(klt_along));
  EXPECT_LE(sift_abs.back(), 0.6);
  EXPECT_LE(with_sift.max_across_m, 0.1);
  EXPECT_LT(with_sift.max_across_m, with_klt.max_across_m);
  EXPECT_LE(with_sift.max_rotation_posed_deg, 0.25);
  EXPECT_LT(with_sift.max_rotation_posed_deg, with_klt.max_rotation_posed_deg);
  // An anchor the along-track profile calls ok (none is here) is right.
  if (with_sift.ok > 0) {
    EXPECT_LE(with_sift.max_horizontal_m, 0.1);
  }
}

// `world`'s query drive and LiDAR map turned by `grade_deg` about the horizontal axis across the
// road through the query's middle, written into `dir` (dir/query, dir/map.ply): the same street
// on a grade. The frames stay as they are (the camera turns with the world); the map, the GNSS
// fixes and the ground truth turn.
void WriteGradedWorld(const std::string& world, double grade_deg, const std::string& dir) {
  const EnuFrame enu(SynthOrigin());
  Drive drive = LoadDrive(world + "/query");
  ASSERT_TRUE(drive.ground_truth.has_value());
  const std::vector<PositionSample>& truth = drive.ground_truth->samples;
  Eigen::Vector3d middle = Eigen::Vector3d::Zero();
  for (const PositionSample& s : truth) middle += enu.ToEnu(s.position);
  middle /= static_cast<double>(truth.size());
  Eigen::Vector3d along = enu.ToEnu(truth.back().position) - enu.ToEnu(truth.front().position);
  along.z() = 0.0;
  const Eigen::Vector3d right = along.normalized().cross(Eigen::Vector3d::UnitZ());
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(grade_deg * kDegToRad, right).toRotationMatrix();
  const auto move = [&](PositionTrack& track) {
    for (PositionSample& s : track.samples) {
      const Geodetic moved = enu.ToGeodetic(turn * (enu.ToEnu(s.position) - middle) + middle);
      if (s.enu_from_cam) {
        s.enu_from_cam = Eigen::Quaterniond(enu.EnuFromLocalEnu(moved).transpose() * turn *
                                            enu.EnuFromLocalEnu(s.position) *
                                            s.enu_from_cam->toRotationMatrix());
      }
      s.position = moved;
    }
  };
  move(*drive.ground_truth);
  move(drive.gnss);
  WriteDrive(drive, dir + "/query");
  PointCloud map = ReadPointCloud(world + "/lidar/map.ply");
  for (Eigen::Vector3f& p : map.positions) {
    p = (turn * (p.cast<double>() - middle) + middle).cast<float>();
  }
  WritePointCloud(dir + "/map.ply", map);
}

// The synthetic street's default 15 Hz query (`epiloc synth --length-m 50 --seed 3`: 165 frames,
// 42 anchors every 4th frame), SIFT structure along its VO poses: issue 17's synthetic targets
// (<= 0.05 m and 0.1 deg) and what the along-track profile calls ok.
TEST(StructureAnchor, SiftStructurePlacesTheFifteenHertzQuery) {
  SynthOptions synth;
  synth.length_m = 50.0;
  synth.seed = 3;
  const std::string world = SharedWorld("epiloc_anchor_test_world_15hz_v1", synth);
  const Drive query = LoadDrive(world + "/query");
  const VoStructure klt = VoStructure::FromResult(RunVisualOdometry(query, VoOptions()));
  BuildDbOptions build;
  build.num_threads = 2;
  const VoStructure sift = TriangulateAlongVo(world + "/query", klt, build);
  const AnchorDriveResult result = AnchorDriveByStructure(QueryInputs(world), sift, QueryOptions());
  const Errors e = Compare(result, query, EnuFrame(SynthOrigin()));
  ASSERT_EQ(e.posed, e.total);
  ASSERT_GE(e.total, 40);
  // The prior offset written is the pose's as written, after the consensus placement moved it.
  const EnuFrame enu(SynthOrigin());
  int moved = 0;
  for (const AnchorResult& a : result.frames) {
    const auto gnss = query.gnss.Interpolate(a.timestamp_s, query.max_gap_s);
    ASSERT_TRUE(gnss.has_value());
    const Eigen::Vector3d offset = enu.ToEnu(a.position) - enu.ToEnu(gnss->position);
    EXPECT_NEAR(a.prior_offset_m, offset.head<2>().norm(), 1e-6) << a.frame;
    moved += a.consensus_move_m > 0.001 ? 1 : 0;
  }
  EXPECT_GT(moved, 0);
  const double max_h = Max(e.posed_horizontal_m);
  const double max_r = Max(e.posed_rotation_deg);
  PrintPosed("15 Hz query, SIFT structure", e);
  // Measured (2026-11-27): 23 of 42 ok, within 0.083 m and 0.099 deg; every anchor: median
  // 0.037 m, max 0.123 m, rotation median 0.066 deg, max 0.099 deg (the CLI with `epiloc vo`'s
  // trajectory: 25 ok, 0.035 / 0.126 m, 0.067 / 0.116 deg). The medians meet the targets, the
  // worst anchors not by position; before the drift pass and the paired along-track test:
  // median 0.049 m, max 0.59 m, rotation max 0.42 deg, none ok. Since the seed follows the
  // road's grade (2026-11-28): 18 ok, within 0.053 m and 0.113 deg; median 0.037 m, max 0.50 m
  // (one rejected anchor, frame 64, landed 0.5 m back; the CLI: 23 ok, 0.037 / 0.245 m); with
  // the profile moves too: 25 ok within 0.055 m and 0.113 deg, the same median and max; and with
  // the tilt held at the coarse levels (StructureRegistrationOptions::hold_tilt_coarse): 24 ok
  // within 0.056 m and 0.088 deg; every anchor median 0.042 m, max 0.084 m, rotation median
  // 0.065 deg, max 0.103 deg. With the rotation consensus (2026-11-28): 29 ok within 0.059 m
  // and 0.095 deg; every anchor median 0.047 m, max 0.074 m, rotation median 0.066 deg, max
  // 0.095 deg (the CLI: 29 ok, 0.046 / 0.065 m, 0.066 / 0.094 deg; before it 0.041 / 0.346 m).
  EXPECT_LE(Median(e.posed_horizontal_m), 0.05);
  EXPECT_LE(Median(e.posed_rotation_deg), 0.1);
  EXPECT_LE(max_h, 0.15);
  // The rotation target (0.1 deg) on every anchor since the map bundle
  // (StructureAnchorOptions::map_bundle, 2026-12-06, sixth session): 0.094 -> 0.043 deg.
  EXPECT_LE(max_r, 0.1);
  // What is called ok is right, and so is a good share of the anchors. Since the along-road
  // profile also grades the points' costs (StructureRegistration::along_ambiguity_m,
  // 2026-11-28, fourth session): 37 of 42 ok (29 before), within 0.059 m and 0.095 deg. With the
  // ok claim at the profile's resolution (max_along_sigma_m 0.15, 2026-12-06): 41 of 42 ok within
  // 0.066 m and 0.094 deg; dense map 42 of 42, 2 deg grade 42 of 42 (within 0.100 m), sparse map
  // 25 of 42 (within 0.056 m). With the consensus placement (StructureAnchorOptions::
  // consensus_placement, the same day): the ok anchors within 0.062 / 0.051 / 0.070 / 0.064 m.
  // With the placing registration's parallax floor (StructureAnchorOptions::min_parallax_deg,
  // 2026-12-06, fifth session): 41 of 42 ok within 0.030 m and 0.094 deg; every anchor median
  // 0.023 m, max 0.031 m (0.048 / 0.075 m without); the dense map 0.044 m, 2 deg grade 0.037 m,
  // sparse map 0.047 m (31 ok). The position target (0.05 m) is met on all four maps. With the
  // bundle's placement (2026-12-07, fourth session): 42 of 42 ok within 0.029 m and 0.040 deg;
  // dense 0.037 m, grade 0.025 m, sparse 0.058 m (below). With the roll from the images' vertical
  // lines (StructureAnchorOptions::bundle_vertical_lines, fifth session; on the suite's world 2
  // the bundle's rotation 0.18 -> 0.09 deg): 42 of 42 ok within 0.035 m and 0.050 deg; dense
  // 0.044 m / 0.057 deg, grade 0.028 / 0.046, sparse 0.064 m / 0.058 deg (31 of 42 ok): here,
  // where the bundle's roll was already right, the lines' own scatter costs a few millimetres
  // and hundredths of a degree.
  EXPECT_GE(e.ok * 10, e.total * 9);
  EXPECT_LE(e.max_horizontal_m, 0.05);
  EXPECT_LE(max_h, 0.05);
  EXPECT_LE(e.max_rotation_deg, 0.1);

  // Without the floor the thin-parallax points' depths push every anchor ahead along the road
  // (the VO's orientations are a few hundredths of a degree off from frame to frame; with the
  // true poses as the VO the anchors are within 0.02 m): along-road median +0.04 m.
  // Every 8th frame (21 anchors; the suite's time): every anchor was +0.03 to +0.055 m.
  // The map bundle off in this run: since it places the ok anchors (2026-12-07, fourth session)
  // it takes most of this offset away too (along-road median -0.011 m without the floor), and the
  // floor is the registrations' own.
  StructureAnchorOptions every_point = QueryOptions();
  every_point.min_parallax_deg = 0.0;
  every_point.map_bundle = false;
  AnchorInputs every_eighth = QueryInputs(world);
  every_eighth.every = 8;
  const Errors f = Compare(AnchorDriveByStructure(every_eighth, sift, every_point), query,
                           EnuFrame(SynthOrigin()));
  PrintPosed("15 Hz query, no parallax floor", f);
  EXPECT_GT(Median(f.along_m), 0.025);
  // With the floor the registrations' median was within 0.015 m; the bundle's placement leaves
  // -0.022 m (its own along-road offset: with the true poses as the VO, on the suite's world 2,
  // -0.018 m against the registrations' -0.011 m).
  EXPECT_LT(std::abs(Median(e.along_m)), 0.03);
  EXPECT_GT(Max(f.posed_horizontal_m), max_h);

  // The same structure against a denser map of the same world: a scan every 2.5 m instead of
  // 10, 128 beams instead of 64, all around instead of the forward half (`synth --lidar-spacing
  // 2.5 --lidar-rings 128 --lidar-fov 360`). The map limits the along-track fix: here every
  // anchor meets the position target.
  // The same query and structure against another map of the same world: `scan_spacing_m`
  // apart, `rings` beams, over `fov_deg`.
  const auto against_map = [&](const std::string& name, double scan_spacing_m, int rings,
                               double fov_deg) {
    SynthOptions map_synth = synth;
    map_synth.survey_frames = false;
    map_synth.lidar_options.scan_spacing_m = scan_spacing_m;
    map_synth.lidar_options.num_rings = rings;
    map_synth.lidar_options.azimuth_fov_deg = fov_deg;
    AnchorInputs inputs = QueryInputs(world);
    inputs.cloud_path = SharedWorld(name, map_synth) + "/lidar/map.ply";
    return Compare(AnchorDriveByStructure(inputs, sift, QueryOptions()), query,
                   EnuFrame(SynthOrigin()));
  };
  const Errors d = against_map("epiloc_anchor_test_world_15hz_dense_v1", 2.5, 128, 360.0);
  ASSERT_EQ(d.posed, d.total);
  const double dense_max_h = Max(d.posed_horizontal_m);
  const double dense_max_r = Max(d.posed_rotation_deg);
  PrintPosed("dense map", d);
  // Measured (2026-11-27, the CLI): 38 of 42 ok; every anchor: median 0.028 m, max 0.041 m,
  // rotation median 0.079 deg, max 0.113 deg (the rotation's worst just misses 0.1 deg). Since
  // the profile moves (StructureRegistrationOptions::profile_moves, 2026-11-28), in process: 39
  // ok, median 0.029 m, max 0.0505 m: the position target just missed by one anchor (the CLI:
  // 0.030 / 0.045 m); with the tilt held at the coarse levels: 38 ok, median 0.029 m, max
  // 0.044 m, rotation max 0.109 deg; with the rotation consensus: 39 ok, median 0.029 m, max
  // 0.039 m, rotation median 0.080 deg, max 0.101 deg; with the graded profile: 42 of 42 ok.
  // With the consensus placement (2026-12-06): median 0.032 m, max 0.051 m (0.046 before): the
  // target (0.05 m) missed by 1 mm at the worst anchor; on KITTI the same pass lowers the worst
  // ok anchor 0.19-0.41 -> 0.14-0.31 m (StructureAnchorOptions::consensus_placement).
  EXPECT_LE(Median(d.posed_horizontal_m), 0.04);
  EXPECT_LE(dense_max_h, 0.05);
  EXPECT_LE(Median(d.posed_rotation_deg), 0.1);
  // With the map bundle: rotation max 0.101 -> 0.045 deg.
  EXPECT_LE(dense_max_r, 0.1);
  EXPECT_GE(d.ok * 10, d.total * 9);
  EXPECT_LE(d.max_horizontal_m, 0.05);

  // The same street on a 2 degree grade (3.5 %), the same frames and structure. Measured
  // (2026-11-28): 21 of 42 ok, within 0.063 m and 0.094 deg; every anchor: median 0.055 m, max
  // 0.51 m, rotation median 0.067 deg, max 0.17 deg (with the profile moves: 22 ok, the same;
  // with the tilt held at the coarse levels: 27 ok within 0.072 m and 0.101 deg, every anchor
  // median 0.053 m, max 0.096 m, rotation max 0.164 deg; with the rotation consensus: 30 ok
  // within 0.063 m and 0.086 deg, every anchor median 0.053 m, max 0.095 m, rotation max
  // 0.086 deg).
  // Without the seed's grade (StructureAnchorOptions::seed_grade) and the seed search's height
  // tolerance (StructureRegistrationOptions::search_height_m), as before: 5 ok (within 0.06 m),
  // every anchor median 1.71 m, max 8.07 m.
  TempDir graded;
  WriteGradedWorld(world, 2.0, graded.str());
  AnchorInputs graded_inputs = QueryInputs(world);
  graded_inputs.cloud_path = graded / "map.ply";
  graded_inputs.drive_dir = graded / "query";
  const Drive graded_query = LoadDrive(graded / "query");
  const Errors g = Compare(AnchorDriveByStructure(graded_inputs, sift, QueryOptions()),
                           graded_query, EnuFrame(SynthOrigin()));
  ASSERT_EQ(g.posed, g.total);
  PrintPosed("2 deg grade", g);
  EXPECT_LE(Median(g.posed_horizontal_m), 0.08);
  EXPECT_LE(Median(g.posed_rotation_deg), 0.1);
  EXPECT_LE(Max(g.posed_horizontal_m), 0.05);
  EXPECT_LE(Max(g.posed_rotation_deg), 0.1);
  // With the graded profile: 33 of 42 ok (30 before); with the ok claim at 0.3 m, 42.
  EXPECT_GE(g.ok * 10, g.total * 9);
  EXPECT_LE(g.max_horizontal_m, 0.05);

  // A sparser map of the same world: a scan every 20 m instead of 10, 32 beams instead of 64.
  // Few of its points lie on surfaces facing along the road, and a move of the fit along it
  // takes few points off the surface; the graded profile counts how far they move within it.
  // Measured (2026-11-28, fourth session): 18 of 42 ok within 0.053 m (3 with the counts' test
  // alone, the CLI); every anchor median 0.046 m, max 0.125 m, rotation median 0.122 deg, max
  // 0.172 deg (the rotation target is missed on this map).
  const Errors sp = against_map("epiloc_anchor_test_world_15hz_sparse_v1", 20.0, 32,
                                synth.lidar_options.azimuth_fov_deg);
  ASSERT_EQ(sp.posed, sp.total);
  PrintPosed("sparse map", sp);
  EXPECT_LE(Median(sp.posed_horizontal_m), 0.06);
  // Since the map bundle places the ok anchors (2026-12-07, fourth session) 0.047 -> 0.058 m, every
  // anchor about 0.05 m behind (on the suite's sparse map, worlds 1 and 2: 0.032 -> 0.019 m and
  // 0.092 -> 0.058 m; the other maps here: 15 Hz 0.031 -> 0.029 m, dense 0.044 -> 0.037 m, grade
  // 0.037 -> 0.025 m): the position target is missed on this map again. With the roll from the
  // vertical lines (2026-12-07, fifth session) 0.058 -> 0.064 m (rotation 0.080 -> 0.058 deg):
  // 0.075 leaves the VO's run-to-run spread a margin.
  EXPECT_LE(Max(sp.posed_horizontal_m), 0.075);
  // With the map bundle (2026-12-06, sixth session): rotation median 0.120 -> 0.054 deg, max
  // 0.169 -> 0.080 deg: the VO's structure turned against its cameras (mostly roll) and the
  // sparse map's own turn no longer reach the camera (README "The map bundle").
  EXPECT_LE(Max(sp.posed_rotation_deg), 0.1);
  EXPECT_GE(sp.ok * 2, sp.total);
  EXPECT_LE(sp.max_horizontal_m, 0.075);
}

TEST(StructureAnchor, FramesWithoutVoPoseAreLostAndBadInputThrows) {
  const std::string world = SharedSyntheticWorld();
  VoStructure vo;
  StampedPose pose;
  pose.timestamp_s = -1000.0;  // on no frame of the drive
  vo.poses.push_back(pose);
  AnchorInputs inputs;
  inputs.cloud_path = world + "/lidar/map.ply";
  inputs.map_origin = SynthOrigin();
  inputs.drive_dir = world + "/query";
  inputs.vo_path = "vo.tum";
  ExpectError([&] { AnchorDriveByStructure(inputs, vo, StructureAnchorOptions()); },
              {"vo.tum: no VO pose falls on a frame time"});
  TempDir dir;
  WriteText(dir / "vo.tum", "0 0 0 0 0 0 0 1\n");
  ExpectError([&] { VoStructure::Read(dir / "vo.tum"); }, {"vo.points.csv: no VO points file"});
  StructureAnchorOptions bad;
  bad.window_m = 0.0;
  ExpectError([&] { bad.Check(); }, {"window_m must be > 0"});
  StructureAnchorOptions negative_radius;
  negative_radius.consensus_radius_m = -0.1;
  ExpectError([&] { negative_radius.Check(); }, {"consensus_radius_m must be >= 0"});
  for (const double angle : {-1.0, 90.0, std::nan("")}) {
    StructureAnchorOptions bad_parallax;
    bad_parallax.min_parallax_deg = angle;
    ExpectError([&] { bad_parallax.Check(); }, {"min_parallax_deg must be in [0, 90)"});
  }
  for (const double radius : {0.0, -40.0, std::nan("")}) {
    StructureAnchorOptions no_placement_radius;
    no_placement_radius.placement_rotation_radius_m = radius;
    ExpectError([&] { no_placement_radius.Check(); }, {"placement_rotation_radius_m must be > 0"});
  }
  // The SIFT structure of a drive that is not there: the error names it.
  ExpectError([&] { TriangulateAlongVo(dir / "missing_drive", vo, BuildDbOptions()); },
              {"missing_drive"});
}

}  // namespace
}  // namespace epiloc
