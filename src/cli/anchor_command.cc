#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "cli_common.h"
#include "epiloc/anchor/anchor.h"
#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/anchor/structure_sift.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/georef/trajectory_import.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/result.h"
#include "epiloc/io/stella_map.h"

namespace epiloc {
namespace {

// The VO's scale change (ScaleTrendOfAnchors) above which `anchor` warns: 10 % per 100 m is 4 %
// over the default 40 m window.
constexpr double kScaleTrendWarningPercentPer100m = 10.0;

// The trajectory of --vo (ImportTrajectory: any format georef reads, its times put on the
// drive's clock) with its points (--vo-points, else those of a stella_vslam map, else the points
// file beside it when there, else none).
VoStructure ReadVoForAnchoring(const Drive& drive,
                               const std::string& vo_path,
                               TrajectoryImportOptions import,
                               const std::string& points_path) {
  SetDriveFrames(drive, &import);
  StellaMap stella_map;
  const ImportedTrajectory trajectory = ImportTrajectory(vo_path, import, &stella_map);
  if (trajectory.format == TrajectoryFileFormat::kStellaMap && points_path.empty()) {
    VoStructure vo = VoStructure::FromStellaMap(stella_map, trajectory.poses, vo_path);
    spdlog::info(
        "structure: {} landmarks of the stella_vslam map {} seen from 2+ of its {} keyframes",
        vo.points.size(), vo_path, vo.poses.size());
    return vo;
  }
  if (trajectory.format == TrajectoryFileFormat::kStellaMap) {
    // The points of --vo-points (a binary map holds no "# segment" comments: one segment).
    VoStructure vo;
    vo.poses = trajectory.poses;
    vo.points = ReadVoPoints(points_path);
    return vo;
  }
  std::string points = points_path;
  if (points.empty() && std::filesystem::exists(VoPointsPath(vo_path))) {
    points = VoPointsPath(vo_path);
  }
  return VoStructure::FromPoses(trajectory.poses, vo_path, points);
}

// The poses of `vo` at the drive's frames: a frame's own pose (within 1 ms), else one
// interpolated between the poses around it when they are at most max_gap_s apart and of one VO
// segment (a keyframe trajectory, as ORB-SLAM's KeyFrameTrajectory.txt, then anchors every
// frame); frames with neither get none. `interpolated` gets the count of the latter kind.
std::vector<StampedPose> PosesAtFrames(const VoStructure& vo,
                                       const Drive& drive,
                                       double max_gap_s,
                                       int* interpolated) {
  *interpolated = 0;
  std::vector<StampedPose> at_frames;
  size_t j = 0;  // the first pose at or after the frame's time
  for (const FrameRecord& f : drive.frames) {
    const double t = f.timestamp_s;
    while (j < vo.poses.size() && vo.poses[j].timestamp_s < t - 1e-3) ++j;
    if (j < vo.poses.size() && std::abs(vo.poses[j].timestamp_s - t) <= 1e-3) {
      at_frames.push_back(vo.poses[j]);
      continue;
    }
    if (j == 0 || j == vo.poses.size()) continue;
    const StampedPose& before = vo.poses[j - 1];
    const StampedPose& after = vo.poses[j];
    const int segment = vo.SegmentOf(before.frame);
    if (segment < 0 || segment != vo.SegmentOf(after.frame)) continue;
    const std::optional<Rigid3d> pose = InterpolatePose({before, after}, t, max_gap_s);
    if (!pose) continue;
    StampedPose p;
    p.timestamp_s = t;
    p.frame = f.frame;
    p.world_from_cam = *pose;
    at_frames.push_back(p);
    ++*interpolated;
  }
  return at_frames;
}

// "N", "A:B" or "A:B:S" items (B exclusive), comma-separated: "0,5,10:20:2".
std::vector<frame_t> ParseFrameList(const std::string& text) {
  std::vector<frame_t> frames;
  const std::string where = "--frames '" + text + "'";
  for (const std::string& item : SplitCsvLine(text)) {
    std::vector<std::string> parts;
    size_t begin = 0;
    while (true) {
      const size_t colon = item.find(':', begin);
      parts.push_back(item.substr(begin, colon - begin));
      if (colon == std::string::npos) break;
      begin = colon + 1;
    }
    if (parts.size() == 1) {
      frames.push_back(ParseInt(parts[0], where));
      continue;
    }
    if (parts.size() > 3) Throw("{}: expected N, START:STOP or START:STOP:STEP items", where);
    const int64_t start = ParseInt(parts[0], where);
    const int64_t stop = ParseInt(parts[1], where);
    const int64_t step = parts.size() == 3 ? ParseInt(parts[2], where) : 1;
    if (step < 1) Throw("{}: the step must be >= 1", where);
    for (int64_t f = start; f < stop; f += step) frames.push_back(f);
  }
  if (frames.empty()) Throw("{}: no frames", where);
  return frames;
}

ResultStatus ToResultStatus(AnchorStatus status) {
  switch (status) {
    case AnchorStatus::kOk:
      return ResultStatus::kOk;
    case AnchorStatus::kRejected:
      return ResultStatus::kRejected;
    default:
      return ResultStatus::kLost;
  }
}

std::string Fixed(double value, int digits) {
  return std::isfinite(value) ? fmt::format("{:.{}f}", value, digits) : "";
}

// One result row per anchored frame (method "anchor"); the figures as extra columns.
ResultTable ToResultTable(const AnchorDriveResult& anchors,
                          const std::string& path,
                          const std::string& anchor_method) {
  ResultTable table;
  table.path = path;
  table.extra_columns = {"anchor_status",
                         "inliers",
                         "matches",
                         "rmse_px",
                         "prior_offset_m",
                         "x_m",
                         "y_m",
                         "z_m",
                         "candidate",
                         "rounds",
                         "seconds",
                         "anchor_method",
                         "scale_m_per_unit",
                         "seed_scale",
                         "inlier_share",
                         "residual_m",
                         "along_info",
                         "along_sigma_m",
                         "structure_points",
                         "scale_drift_per_m",
                         "consensus_move_m",
                         "bundle_move_m",
                         "message"};
  for (const AnchorResult& a : anchors.frames) {
    ResultRow row;
    row.frame = a.frame;
    row.timestamp_s = a.timestamp_s;
    row.method = "anchor";
    row.status = ToResultStatus(a.status);
    const Eigen::Vector3d x = a.map_from_cam.translation;
    if (a.has_pose) {
      row.position = a.position;
      row.has_position = true;
      row.enu_from_cam = a.enu_from_cam;
    }
    row.extra = {AnchorStatusName(a.status),
                 std::to_string(a.num_inliers),
                 std::to_string(a.num_matches),
                 a.has_pose ? Fixed(a.rmse_px, 3) : "",
                 a.has_pose ? Fixed(a.prior_offset_m, 3) : "",
                 a.has_pose ? Fixed(x.x(), 4) : "",
                 a.has_pose ? Fixed(x.y(), 4) : "",
                 a.has_pose ? Fixed(x.z(), 4) : "",
                 std::to_string(a.best_candidate),
                 std::to_string(a.rounds),
                 Fixed(a.seconds, 3),
                 anchor_method,
                 Fixed(a.scale_m_per_unit, 6),
                 Fixed(a.seed_scale_m_per_unit, 6),
                 Fixed(a.inlier_share, 3),
                 Fixed(a.residual_m, 4),
                 Fixed(a.along_information, 4),
                 Fixed(a.along_sigma_m, 4),
                 std::to_string(a.structure_points),
                 Fixed(a.scale_drift_per_m, 6),
                 Fixed(a.consensus_move_m, 4),
                 Fixed(a.bundle_move_m, 4),
                 a.message};
    table.rows.push_back(std::move(row));
  }
  return table;
}

}  // namespace

int RunAnchor(int argc, char** argv) {
  CLI::App app(
      "Anchor camera frames in a LiDAR map. structure (the default with --vo): the drive's "
      "monocular VO points over a sliding window are registered to the map by a GPS-seeded "
      "robust ICP with scale (Sim(3)), no appearance matching. render / photos: candidate poses "
      "around the GPS prior are rendered (or the map's photographs used), matched with the "
      "undistorted frame (AKAZE or SIFT), lifted to 3-D and solved by PnP RANSAC + LM, then "
      "refined. Writes a result CSV (method anchor) that epiloc evaluate and georef read.",
      "anchor");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  AnchorInputs inputs;
  AnchorOptions options;
  std::string frames_text, out_path, origin_text, db_path, matcher = "akaze", shading = "auto";
  std::string method = "auto", vo_points_path, structure_source = "auto", scale_drift = "anchors";
  StructureAnchorOptions structure;
  app.add_option("--cloud", inputs.cloud_path, "Map: point-cloud file or tile directory")
      ->required();
  app.add_option("--drive", inputs.drive_dir, "Drive whose frames are anchored")->required();
  auto* frames_option = app.add_option(
      "--frames", frames_text, "Frame numbers: N, START:STOP[:STEP] (STOP exclusive), comma list");
  app.add_option("--every", inputs.every, "Every n-th frame of the drive (without --frames)")
      ->excludes(frames_option)
      ->capture_default_str();
  app.add_option("--out", out_path, "Result CSV to write")->required();
  app.add_option("--cloud-origin", origin_text,
                 "LAT,LON,ALT of the cloud's ENU origin (when it has no sidecar)");
  app.add_option("--db", db_path, "Route database whose ENU origin the cloud uses (no sidecar)");
  app.add_option("--heading-error-deg", options.heading_error_deg,
                 "Testing: perturb each prior heading by a seeded uniform error in +-D degrees")
      ->capture_default_str();
  app.add_option("--seed", options.seed, "Seed of the heading perturbation and random candidates")
      ->capture_default_str();
  app.add_option("--candidates", options.candidates.num_candidates,
                 "Candidate poses rendered per frame, the prior included")
      ->capture_default_str();
  app.add_option("--along-range", options.candidates.along_range_m,
                 "Candidates: along-track offsets up to +-this, metres (about the GNSS sigma)")
      ->capture_default_str();
  app.add_option("--lateral-range", options.candidates.lateral_range_m,
                 "Candidates: lateral offsets up to +-this, metres")
      ->capture_default_str();
  app.add_option("--yaw-range", options.candidates.yaw_range_deg,
                 "Candidates: heading offsets up to +-this, degrees")
      ->capture_default_str();
  app.add_option("--matcher", matcher, "akaze | sift")->capture_default_str();
  app.add_option("--match-scale", options.matching.scale,
                 "Frame and rendering are resized by this before feature detection")
      ->capture_default_str();
  app.add_option("--match-blur", options.matching.blur_sigma_px,
                 "Gaussian blur (pixels, at the detection scale) before feature detection")
      ->capture_default_str();
  app.add_option("--ratio", options.matching.ratio, "Lowe's ratio test threshold")
      ->capture_default_str();
  app.add_option("--shading", shading, "Rendering: auto | intensity | colour")
      ->capture_default_str();
  app.add_option("--camera-height", options.prior.camera_height_m,
                 "Camera above the road, metres (the prior's height over the map's ground)")
      ->capture_default_str();
  app.add_option("--gnss-sigma", options.gnss_sigma_m,
                 "Horizontal GNSS sigma, metres; poses more than 4 sigma away are rejected")
      ->capture_default_str();
  app.add_option("--min-inliers", options.min_inliers, "Fewer PnP inliers: rejected")
      ->capture_default_str();
  app.add_option("--max-rmse", options.max_rmse_px, "Higher reprojection RMSE (px): rejected")
      ->capture_default_str();
  app.add_option("--pnp-max-error", options.pnp.max_reprojection_px,
                 "PnP RANSAC inlier threshold, pixels")
      ->capture_default_str();
  app.add_option("--refine-rounds", options.refine_rounds,
                 "Re-renders at the solved pose (the centimetre step)")
      ->capture_default_str();
  app.add_flag("--photometric", options.photometric,
               "Finish with direct photometric refinement against the rendering");
  app.add_option("--map-photos", inputs.photos_dir,
                 "Drive of the map's photographs (frames + oriented poses, e.g. the drive "
                 "build-map --colorize used): frames are matched to them, lifted onto the map, "
                 "instead of to renderings (much more accurate and robust)");
  app.add_option("--photos-per-pose", inputs.photos.max_views,
                 "Map photographs matched per refinement round, nearest first")
      ->capture_default_str();
  app.add_option("--splat-size", options.render.splat_size_m, "Metric splat size, metres")
      ->capture_default_str();
  app.add_option("--threads", options.num_threads, "Frames anchored in parallel")
      ->capture_default_str();
  app.add_option("--method", method,
                 "auto | structure | render | photos (auto: photos with --map-photos, else "
                 "structure with --vo, else render)")
      ->capture_default_str();
  app.add_option("--vo", inputs.vo_path,
                 "structure: the drive's monocular trajectory (epiloc vo TUM with its points file "
                 "beside it; ORB-SLAM2/3, stella_vslam: TUM or KITTI poses, anchored with the "
                 "drive's SIFT structure)");
  app.add_option("--vo-points", vo_points_path,
                 "structure: the VO points CSV (default: beside --vo, .points.csv, when there)");
  std::string vo_format = "auto";
  TrajectoryImportOptions import;
  AddTrajectoryImportOptions(app, import, vo_format);
  double max_gap_s = 1.0;
  app.add_option("--max-gap-s", max_gap_s,
                 "structure: a frame between two VO poses at most this far apart (seconds, one "
                 "VO segment) gets the interpolated pose (keyframe trajectories)")
      ->capture_default_str();
  app.add_option("--structure", structure_source,
                 "structure: the points registered to the map: vo (the VO's own KLT points), sift "
                 "(the drive's SIFT features triangulated along the VO poses) or auto (vo; where "
                 "its anchors' median along-road sigma is not below --max-along-sigma, sift too, "
                 "and the better fixed kept)")
      ->capture_default_str();
  app.add_option("--consensus-radius", structure.consensus_radius_m,
                 "structure: anchors farther than this from their neighbours' agreed placement "
                 "are registered again from it, metres (0: off)")
      ->capture_default_str();
  app.add_option("--consensus-placement", structure.consensus_placement,
                 "structure: each ok anchor moved to the median of its ok neighbours' placements "
                 "of its camera, itself included (true/false; the move in consensus_move_m)")
      ->capture_default_str();
  app.add_option("--exchange-rounds", structure.exchange_rounds,
                 "structure: after the first pass, each anchor registered again from the fits of "
                 "its neighbours that put more of their points on the map and place it elsewhere, "
                 "the fit with most points on the map kept; at most this many rounds (0: off)")
      ->capture_default_str();
  app.add_option("--auto-min-ok-share", structure.auto_min_ok_share,
                 "structure auto: where the VO's points leave fewer anchors ok than this share of "
                 "the frames, the SIFT structure's run too, the one with more ok anchors kept")
      ->capture_default_str();
  app.add_option("--rotation-consensus", structure.rotation_consensus,
                 "structure: each anchor registered again with the median rotation of the anchors "
                 "whose windows overlap its own held (true/false)")
      ->capture_default_str();
  app.add_option("--placement-rotation-radius", structure.placement_rotation_radius_m,
                 "structure: with --rotation-consensus, the structure is registered with the "
                 "median rotation of the anchors within this radius (the camera is turned by "
                 "those within --window), metres")
      ->capture_default_str();
  app.add_option("--scale-drift", scale_drift,
                 "structure: the VO's scale drift along a window: anchors (from the scales of "
                 "the anchors around, then each registered again with it), window (estimated in "
                 "each window's fit) or none")
      ->capture_default_str();
  app.add_option("--max-scale-drift", structure.registration.max_scale_drift_per_m,
                 "structure: the scale drift at most, relative change of scale per metre of road")
      ->capture_default_str();
  app.add_option("--window", structure.window_m,
                 "structure: road length of the keyframe window, metres")
      ->capture_default_str();
  app.add_option("--max-point-range", structure.max_point_range_m,
                 "structure: VO points farther from the window's cameras are not used, metres")
      ->capture_default_str();
  app.add_option("--min-parallax", structure.min_parallax_deg,
                 "structure: with --rotation-consensus, the registration that places the camera "
                 "(rotation held) leaves out the VO points whose first and last rays meet at a "
                 "smaller angle (their depth is the least certain), degrees")
      ->capture_default_str();
  app.add_option("--map-bundle", structure.map_bundle,
                 "structure: last, where the structure keeps its sightings (--structure sift), "
                 "the cameras around the anchors and the points they saw adjusted to the images "
                 "and the map's planes together; each anchor takes its camera's rotation from it")
      ->capture_default_str();
  app.add_option("--bundle-vertical-lines", structure.bundle_vertical_lines,
                 "structure: the map bundle also holds each camera's roll near the one its "
                 "image's near-vertical line segments show (building edges, poles), within their "
                 "fit's uncertainty")
      ->capture_default_str();
  app.add_option("--bundle-window", structure.bundle_window_m,
                 "structure: the map bundle takes the cameras within half this road length of "
                 "an anchor, metres")
      ->capture_default_str();
  app.add_option("--max-points", structure.max_points, "structure: VO points per window at most")
      ->capture_default_str();
  app.add_option("--map-voxel", structure.map_voxel_m,
                 "structure: the map is voxel-filtered to this before the ICP, metres")
      ->capture_default_str();
  app.add_option("--min-inlier-share", structure.min_inlier_share,
                 "structure: reliability, share of points on the map's surfaces at least")
      ->capture_default_str();
  app.add_option("--max-residual", structure.max_rms_m,
                 "structure: reliability, RMS distance to the map's surfaces at most, metres")
      ->capture_default_str();
  app.add_option("--max-along-sigma", structure.max_along_sigma_m,
                 "structure: reliability, position sigma along the road at most, metres (the "
                 "Hessian's, or half the stretch the along-track profile does not tell apart)")
      ->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  if (method == "auto") {
    method = !inputs.photos_dir.empty() ? "photos"
             : !inputs.vo_path.empty()  ? "structure"
                                        : "render";
  }
  if (scale_drift == "none") {
    structure.scale_drift = ScaleDriftModel::kNone;
  } else if (scale_drift == "anchors") {
    structure.scale_drift = ScaleDriftModel::kAcrossAnchors;
  } else if (scale_drift == "window") {
    structure.scale_drift = ScaleDriftModel::kPerWindow;
  } else {
    Throw("--scale-drift: unknown model '{}' (anchors, window, none)", scale_drift);
  }
  if (structure_source != "sift" && structure_source != "vo" && structure_source != "auto") {
    Throw("--structure: unknown structure '{}' (auto, sift, vo)", structure_source);
  }
  if (method != "structure" && method != "render" && method != "photos") {
    Throw("--method: unknown anchoring method '{}' (auto, structure, render, photos)", method);
  }
  EPILOC_CHECK(method != "structure" || !inputs.vo_path.empty(),
               "--method structure needs --vo (a monocular trajectory)");
  EPILOC_CHECK(max_gap_s >= 0, "--max-gap-s must be >= 0");
  EPILOC_CHECK(method != "structure" || inputs.photos_dir.empty(),
               "--method structure does not use --map-photos");
  EPILOC_CHECK(method != "photos" || !inputs.photos_dir.empty(),
               "--method photos needs --map-photos DRIVE");
  CheckCommandOutputs({{"--out", out_path}}, {{"--cloud", inputs.cloud_path},
                                              {"--drive", inputs.drive_dir},
                                              {"--map-photos", inputs.photos_dir},
                                              {"--vo", inputs.vo_path},
                                              {"--vo-points", vo_points_path},
                                              {"--vo-times", import.times_path},
                                              {"--db", db_path}});

  MapOriginInputs origin_inputs{inputs.cloud_path, std::nullopt, db_path};
  if (!origin_text.empty())
    origin_inputs.explicit_origin = ParseGeodetic(origin_text, "--cloud-origin");
  const MapOrigin origin = ResolveMapOrigin(origin_inputs);
  inputs.map_origin = origin.enu_origin;
  if (inputs.photos_dir.empty() && inputs.vo_path.empty() && origin.sidecar &&
      !origin.sidecar->source_dir.empty() &&
      std::filesystem::is_directory(origin.sidecar->source_dir)) {
    spdlog::info(
        "the map was built from drive {}: if it has camera frames, --map-photos {} matches "
        "them instead of renderings (far more robust on sparse maps)",
        origin.sidecar->source_dir, origin.sidecar->source_dir);
  }
  if (!frames_text.empty()) inputs.frames = ParseFrameList(frames_text);
  options.matching.type = ParseFeatureType(matcher);
  options.render.shading = ParseRenderShading(shading);

  AnchorDriveResult result;
  Progress progress("anchor", 0);
  VoStructure vo_segments;  // the VO's segments only (the scale trend, below)
  if (method == "structure") {
    structure.prior.camera_height_m = options.prior.camera_height_m;
    structure.gnss_sigma_m = options.gnss_sigma_m;
    structure.heading_error_deg = options.heading_error_deg;
    structure.seed = options.seed;
    structure.num_threads = options.num_threads;
    import.format = ParseTrajectoryFileFormat(vo_format);
    // The trajectory first: its errors name the file the user gave for this method.
    EPILOC_CHECK(std::ifstream(inputs.vo_path).good(), "{}: cannot open the trajectory",
                 inputs.vo_path);
    const Drive drive = LoadDrive(inputs.drive_dir);
    VoStructure vo = ReadVoForAnchoring(drive, inputs.vo_path, import, vo_points_path);
    vo_segments.segments = vo.segments;
    const size_t read_poses = vo.poses.size();
    int interpolated = 0;
    vo.poses = PosesAtFrames(vo, drive, max_gap_s, &interpolated);
    EPILOC_CHECK(!vo.poses.empty(),
                 "{}: no pose at any frame time of drive {} (its clock: --relative-times or "
                 "--time-offset-s)",
                 inputs.vo_path, inputs.drive_dir);
    if (interpolated > 0) {
      spdlog::info("structure: {} frames between the {} poses of {} take interpolated poses",
                   interpolated, read_poses, inputs.vo_path);
    }
    if (vo.points.empty() && structure_source != "sift") {
      const std::string points =
          vo_points_path.empty() ? VoPointsPath(inputs.vo_path) : vo_points_path;
      EPILOC_CHECK(structure_source == "auto",
                   "--structure vo: no VO points for {} ({} {}; --vo-points FILE), or use "
                   "--structure sift (the drive's SIFT features along its poses)",
                   inputs.vo_path, points,
                   std::filesystem::exists(points) ? "holds none" : "not there");
      spdlog::info("structure: {} comes without points: the drive's SIFT structure is used",
                   inputs.vo_path);
      structure_source = "sift";
    }
    // The drive's SIFT features triangulated along the VO poses (structure_sift.h).
    const auto sift_structure = [&] {
      BuildDbOptions build;
      build.num_threads = options.num_threads;
      SiftStructureSummary sift;
      Progress triangulation("structure", 0);
      VoStructure triangulated =
          TriangulateAlongVo(inputs.drive_dir, vo, build, &sift, triangulation.Callback());
      triangulation.Finish();
      spdlog::info(
          "structure: {} SIFT points (mean track {:.1f} frames) triangulated along the VO poses "
          "of {} frames in {} segment(s), {:.1f} s",
          sift.points, sift.mean_track_length, sift.frames, sift.segments, sift.seconds);
      return triangulated;
    };
    if (structure_source == "sift") {
      result = AnchorDriveByStructure(inputs, sift_structure(), structure, progress.Callback());
    } else if (structure_source == "vo") {
      result = AnchorDriveByStructure(inputs, vo, structure, progress.Callback());
    } else {
      // The VO's points first; where they do not fix the anchors along the road, the SIFT
      // structure too, and the better fixed one gets the passes; where they leave too few anchors
      // ok in the end, the SIFT structure's run too, the one with more ok kept.
      StructureChoice choice;
      const auto after_the_first = [&] {
        progress.Finish();  // the VO's points' first pass
        return sift_structure();
      };
      result = AnchorDriveByStructureAuto(inputs, vo, after_the_first, structure,
                                          progress.Callback(), &choice);
      if (choice.decided_by_ok) {
        spdlog::info(
            "structure auto: {} of {} anchors ok with the VO's points (fixed along the road in "
            "the first pass, median sigma {:.3f} m), {} with the SIFT structure: the {} kept",
            choice.first_ok, result.frames.size(), choice.first_sigma_m, choice.alternative_ok,
            choice.alternative_kept ? "SIFT structure" : "VO's points");
      } else if (choice.alternative_tried) {
        spdlog::info(
            "structure auto: median along-road sigma {:.3f} m with the VO's points, {:.3f} m with "
            "the SIFT structure ({}): the {} kept",
            choice.first_sigma_m, choice.alternative_sigma_m,
            choice.decided_by_finished_runs ? "first passes equal, finished runs" : "first pass",
            choice.alternative_kept ? "SIFT structure" : "VO's points");
      } else {
        spdlog::info(
            "structure auto: the VO's points fix the anchors along the road (median sigma {:.3f} "
            "m, first pass), no SIFT structure",
            choice.first_sigma_m);
      }
    }
  } else {
    if (method == "render") inputs.photos_dir.clear();
    result = AnchorDrive(inputs, options, progress.Callback());
  }
  progress.Finish();
  WriteResultCsv(ToResultTable(result, out_path, method), out_path);

  int64_t by_status[5] = {0, 0, 0, 0, 0};
  for (const AnchorResult& a : result.frames) ++by_status[static_cast<int>(a.status)];
  const size_t n = result.frames.size();
  std::printf(
      "%s: %lld of %zu frames anchored (ok), %lld rejected, %lld lost, %lld without map "
      "coverage, %lld without prior; %.2f s per frame (%.1f s wall, %d threads; method %s)\n",
      out_path.c_str(), static_cast<long long>(by_status[0]), n,
      static_cast<long long>(by_status[1]), static_cast<long long>(by_status[2]),
      static_cast<long long>(by_status[3]), static_cast<long long>(by_status[4]),
      n > 0 ? result.seconds / n : 0.0, result.seconds, options.num_threads, method.c_str());
  if (method == "structure") {
    const auto segment_of = [&vo_segments](frame_t f) { return vo_segments.SegmentOf(f); };
    if (const std::optional<VoScaleTrend> trend = ScaleTrendOfAnchors(result, segment_of)) {
      std::printf(
          "VO scale from the ok anchors: %.4f -> %.4f m per unit over %.0f m (%+.1f %% per 100 "
          "m, %d anchors, %d VO segment(s))\n",
          trend->first_scale, trend->last_scale, trend->distance_m, trend->percent_per_100m,
          trend->anchors, trend->segments);
      // 10 % per 100 m is 4 % over the default 40 m window, where one similarity per window
      // already turns and moves the camera (5 % over 40 m: 0.5 deg, 0.12 m; README).
      if (std::abs(trend->percent_per_100m) >= kScaleTrendWarningPercentPer100m) {
        spdlog::warn(
            "the VO's scale changes by {:+.1f} % per 100 m along the drive: a steady change like "
            "this usually comes from the camera's calibration (its radial distortion; README, "
            "\"What the drift responds to\"); the anchors model it (--scale-drift anchors), and "
            "`epiloc calibrate-radial` estimates the term from this map",
            trend->percent_per_100m);
      }
    }
  }
  return kExitOk;
}

}  // namespace epiloc
