// Anchoring from structure (`epiloc anchor --method structure`): absolute 6-DoF camera poses with
// scale in a LiDAR map without photographs and without appearance matching, by registering the
// camera's own monocular VO structure (`epiloc vo` points) to the map's geometry with a
// similarity transform (structure_registration.h; Caselitz et al., IROS 2016).
//
// Per anchored frame f (a frame with a VO pose):
//  1. Window: the VO poses whose GNSS positions lie within +-window_m / 2 along the GNSS track of
//     f's (time order, same segment), and the VO points of that segment observed by keyframes
//     inside the window's frame range (with at least min_observations keyframes).
//  2. Seed (the GPS prior): the VO world is levelled (camera f level); the 2-D similarity that
//     takes the levelled VO centres of the window onto their GNSS positions (least squares) gives
//     the heading (the direction of the window's GNSS track) and the scale (GNSS distance over
//     VO distance); horizontal translation = the mean GNSS offset over the window; height = the
//     map's ground under f plus the camera height.
//  3. Points farther than max_point_range_m (seed scale) from every window camera are dropped
//     (monocular depth grows uncertain with range); robust Sim(3) ICP against the map
//     (voxel-filtered to map_voxel_m) with its own seed search (structure_registration.h) from
//     the seed and from `seed_offsets_m` around it (the best fit by inliers, then residual,
//     wins); optionally refined over a shorter window (refine_window_m).
//  4. The pose of f: map_from_cam = S * world_from_cam(f) (rotation composed, centre mapped).
//     Reliable (`ok`) only with an inlier share >= min_inlier_share, RMS residual
//     <= max_rms_m, scale within max_scale_change of the seed's, conditioning along the road
//     (along_information >= min_along_information, along_sigma_m <= max_along_sigma_m), within
//     max_prior_sigmas * gnss_sigma_m of the GNSS, at camera height over the map's ground and
//     nearly level; else `rejected` with the reason.
//  5. The fits' exchange (exchange_rounds): each anchor registered again from its better-fitting
//     neighbours' similarities, the fit with most points on the map kept.
//  6. Drift pass (ScaleDriftModel::kAcrossAnchors, default): the VO's scale drift at f from the
//     scales of the other anchors around it, then f registered again from its own fit with the
//     structure warped by that drift (StructureDrift); twice, the second round's drift from the
//     first round's scales (each then the scale at its camera), registered from the first
//     pass's fits; then the consensus pass, the rotation consensus (rotation_consensus), the
//     neighbours' check of the ok anchors, their consensus placement (consensus_placement),
//     each camera turned by its orientation consensus (placement_rotation_radius_m) and, last,
//     where the structure keeps its sightings, the map bundle (map_bundle): the cameras and
//     points adjusted to the images and the map's planes together, and each camera turned as
//     the bundle puts it.
// Frames: map = the cloud's local ENU (metres); VO world = the trajectory's frame (its units).
// Accuracy (README, "What to expect"): on the shared KITTI drive against its OXTS camera pose
// about 0.6 m (median), limited by that track, which is 3.7 % short of its own LiDAR and 0.43 deg
// flatter; against a map and truth on the LiDAR's path (`epiloc lidar-track`), camera 1, four
// heading seeds: 16 of 16 ok, median 0.07-0.09 m, max 0.20-0.27 m, rotation max 0.45 deg; the
// ICP's cost on a sparse map and a monocular structure has minima up to a metre apart (even exact
// structure is not placed better there: tools/bench_structure_bound.cc). On the synthetic street
// the VO's KLT points are too noisy to be fixed along the road (their count on the map's surfaces
// is flat within counting noise): along_sigma_m says so and the anchors are rejected; the drive's
// SIFT features triangulated along the VO poses (structure_sift.h) are placed to 0.035 m (median)
// there.
#pragma once

#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "epiloc/anchor/anchor.h"
#include "epiloc/anchor/pose_prior.h"
#include "epiloc/anchor/structure_registration.h"
#include "epiloc/anchor/vertical_lines.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/pose_files.h"
#include "epiloc/io/stella_map.h"
#include "epiloc/vo/visual_odometry.h"

namespace epiloc {

// How the VO's scale drift along a window is handled (StructureDrift: a linear change of scale
// along the VO path about the anchored camera, each point placed from the path's camera in the
// middle of its first and last keyframe; the frame's pose is the warp's fixed point).
enum class ScaleDriftModel {
  kNone,           // one similarity per window
  kAcrossAnchors,  // the drift from the scales of the other anchors around (within half the
                   // window), then each anchor registered again with it from its own fit (no
                   // search, the levels that free the scale); in two rounds (the second's drift
                   // from the first round's scales)
  kPerWindow,      // estimated in each window's registration with the similarity
};

struct StructureAnchorOptions {
  PriorOptions prior;                         // heading from the GNSS track, camera height
  StructureRegistrationOptions registration;  // the ICP
  // The VO's scale drift (at most registration.max_scale_drift_per_m).
  ScaleDriftModel scale_drift = ScaleDriftModel::kAcrossAnchors;
  double window_m = 40.0;                     // road length (GNSS) of the keyframe window, metres
  // The seed holds the frame's camera level; on a grade (or with a camera pitched on its mount)
  // that tilts the structure against the map. With this, the seed is turned about the horizontal
  // axis across the road so that the window's cameras climb as the map's ground beneath them
  // does (SeedGrade in the source).
  bool seed_grade = true;
  int min_observations = 3;                   // VO points seen by fewer keyframes are not used
  double max_point_range_m = 35.0;  // points farther from every window camera are not used
  // The registration that places the camera (the rotation consensus's, with the rotation held)
  // uses only the points whose rays from their first and last observing camera meet at this
  // angle at least (VoPoint::parallax_deg; unknown, NaN: used); the registrations that give the
  // rotations use them all. Rays alpha apart with a relative direction error delta put a point
  // off by about delta / alpha of its depth, not in its bearing: the far, thin-parallax points
  // fix the rotation, but on the surfaces that face the road, which fix the camera along it,
  // their depth errors move it. The error is the VO's frame-to-frame orientation (synthetic
  // street 0.02-0.07 deg, KITTI up to 0.15 deg per two frames in a turn); at the SIFT
  // triangulation's floor (0.75 deg) 0.03 deg is 4 % of a point's depth, at 2 deg 1.5 %.
  // Synthetic 15 Hz street, SIFT structure: every anchor 0.03-0.055 m ahead along the road
  // without (0.02 m with the true poses as the VO), within 0.03 m with it; KITTI, KLT points
  // (the VO's own floor is 1 deg): unchanged within 0.015 m. Without the rotation consensus
  // there is no such registration, and the floor does not apply.
  double min_parallax_deg = 2.0;
  int max_points = 4000;            // at most this many points (evenly subsampled)
  double map_voxel_m = 0.2;         // the map is voxel-filtered to this before the kd-tree (0: no)
  double map_margin_m = 6.0;        // map points farther from the seeded structure's bounds: cut
  double max_shared_radius_m = 400.0;  // maps around a run of at most this radius are loaded
                                       // and filtered once for all frames
  // Further seeds (along-track, lateral offsets in metres, in the prior camera's level frame)
  // tried besides the prior itself; the fit with most inliers (then least residual) wins.
  std::vector<Eigen::Vector2d> seed_offsets_m = {};
  double refine_window_m = 0.0;  // then refined over this road length about f (0: not;
                                 // KITTI: no gain at 10-20 m)
  std::vector<double> refine_distances_m = {0.6, 0.4, 0.25};  // with these distances, no search
  // The fits' exchange, right after the first pass (ExchangeFits in the source): the seed search
  // holds the GNSS seed's scale, and a window's GNSS track (3 m noise) gives a scale 5-10 % off,
  // so a window may settle in a basin at that scale, metres along the road from the right one,
  // with fewer of its points on the map (synthetic street, world 2: 18 of 42 anchors at scale
  // 1.94-2.06, a third of their points on the map, beside neighbours at 2.25 with a half). Each
  // posed anchor is registered again from the similarity of each neighbour (same segment, within
  // half the window) that puts more of its own window's points on the map than the anchor does
  // and places the anchor's camera elsewhere (beyond consensus_radius_m; at most two such
  // placements, the best-fitting neighbour of each), over the levels that free the scale, and
  // keeps the fit that puts most of its points on the map: the first pass's own criterion, with
  // the neighbours' fits as further seeds. Only at a scale within max_scale_change of the GNSS
  // seed's, offered and taken: a structure shrunk far below it can put more of its points on the
  // map than the right one (KLT points, a drive's last window: 0.72 times the seed's scale, 56 %
  // of its points against 51 %); an anchor whose own scale is not within it takes any fit that
  // is. Repeated up to this many rounds while any anchor changes (a right basin spreads by half
  // a window per round); 0: off.
  int exchange_rounds = 2;
  // `--structure auto` (AnchorDriveByStructureAuto): where the first structure's finished run
  // has fewer ok anchors than this share of the frames, the alternative structure's finished run
  // too, and the one with more ok anchors is kept. The reliability target (90 % of the
  // attempted anchors ok): below it the first structure has failed the drive, and the pass over
  // the images that the alternative costs is worth it; above it, not paid. Synthetic street,
  // world 2, VGA query: the VO's points fix the first pass (median sigma 0.012 m) and leave 1 of
  // 42 anchors ok after the passes (weak along the road), the SIFT structure 42 of 42.
  double auto_min_ok_share = 0.9;
  // Consensus: the VO is consistent within a window (synthetic street: 0.008 m), so neighbouring
  // anchors' similarities place a frame's camera alike; a street of repeated facades gives each
  // window's registration peaks a facade period apart, and the anchors that land on another peak
  // than most of their neighbours are registered again from the majority's (see
  // ApplyConsensus in the source). This is the radius of agreement, metres (0: off): twice the
  // finest correspondence distance, the fine levels' reach. The pass also takes ok from an anchor
  // whose neighbours (at least three, itself left out) place it, by the median, farther along the
  // road than its 2 sigma (2 max_along_sigma_m): neighbouring fits are not independent (their
  // windows overlap), so agreement proves little, but disagreement disproves the claim.
  double consensus_radius_m = 0.6;
  // Rotation consensus: a window's fit fixes the structure's rotation poorly where the street is
  // narrow and long (on KITTI its heading varies by 2.8 degrees from anchor to anchor while the
  // VO's own orientation stays within 0.5 degrees of one rotation over the whole drive), and an
  // error in it moves the camera across the road by its distance from the structure's middle.
  // The VO's orientation drifts far more slowly than that: so each anchor's similarity takes the
  // median rotation of the anchors whose windows overlap its own (ConsensusRotations), and the
  // anchor is registered again with that rotation held (translation, scale and drift free, the
  // levels that free the scale, no profile moves), after the consensus pass and before its
  // neighbour check.
  bool rotation_consensus = true;
  // The rotation consensus gives two rotations, each a median over its own radius. The camera's
  // orientation (written, last: OrientByConsensus in the source) is its VO orientation turned by
  // the consensus of the anchors whose windows overlap its own (within window_m): the VO's
  // orientation wanders (KITTI: by 0.8 deg against the unit's attitude around the drive's turn),
  // so the reference for it is near. The rotation the structure is registered with, which places
  // the camera, is the consensus over this radius: a wrong rotation moves the camera across the
  // road by its lever (the distance to the structure's middle, 10-20 m), and the anchors' fitted
  // rotations scatter (KITTI: +-1 deg from anchor to anchor) more than that wander between them,
  // so more of them place better. The VO's structure and its orientations are two estimates that
  // disagree by up to half a degree (its direction of travel in the camera against the truth's),
  // which is why one rotation does not serve both. Twice the window: the anchors whose windows
  // overlap a window that overlaps the anchor's. KITTI on the LiDAR's path, camera 1 and 0, KLT,
  // four heading seeds: radius 40 -> 50 -> 60 -> 80 m, median 0.097-0.114 -> 0.086-0.092 ->
  // 0.068-0.088 -> 0.067-0.088 m (camera 0 0.129-0.140 -> 0.111-0.134), piecewise georef worst
  // of both cameras and both structures 0.347 -> 0.281 m; one radius of 60 m for both instead:
  // rotation max 0.44 -> 0.64 deg. The synthetic street: no change (its anchors' rotations agree
  // within a tenth of a degree). Bounded on a long drive by how far the VO's orientation wanders.
  double placement_rotation_radius_m = 80.0;
  // Consensus placement, last: each ok anchor's horizontal position is the median of the
  // placements of its camera by the ok anchors within half the window, itself included
  // (ConsensusCentres; at least three). The anchors' along-road errors on KITTI are about 0.1 m
  // each and partly independent (the neighbours' check above finds them 0.1-0.3 m apart), so the
  // median of 5-8 placements is nearer the truth than the worst of them: four heading seeds, both
  // cameras and both structures, the worst ok anchor 0.19-0.41 -> 0.14-0.31 m and piecewise
  // georef 0.20-0.45 -> 0.16-0.35 m; but camera 0's median anchor 0.10 -> 0.13 m (a neighbour's
  // rotation error times the lever moves its placement across the road; along the road only, the
  // worst rows stayed 0.31-0.36 m) and on the synthetic dense map the worst 0.046 -> 0.051 m.
  // The anchor's own registration stays in its scale, rotation and flags;
  // AnchorResult::consensus_move_m says how far it was moved.
  bool consensus_placement = true;
  // Map bundle, after everything else (structure_bundle.cc): where the structure keeps its
  // sightings (the SIFT structure, VoPoint::seen; the VO's own points and other SLAM systems'
  // files do not), the posed anchors in chunks (consecutive, one segment, within bundle_chunk_m
  // of the chunk's first; only those called ok place the window and hold the gauge, a rejected
  // one is doubted and takes its camera's rotation only) and for each chunk the cameras within
  // bundle_window_m / 2 of any of its anchors and the points they saw twice or more, adjusted
  // together: reprojection errors (pixels, Huber bundle_huber_px), the points' distances from the
  // map's local planes within each of bundle_distances_m in turn (in units of bundle_plane_sigma_m,
  // Huber 1), every anchor's centre held within bundle_centre_sigma_m of its placement (the gauge
  // along the road where a street's surfaces leave it free). Each anchor takes its camera's
  // rotation from the bundle, and an ok one its camera's horizontal place too
  // (AnchorResult::bundle_move_m; the registrations place the camera in a structure triangulated
  // along the VO's poses, which their errors bend: on the suite's world 2 every anchor of a run
  // 0.05-0.07 m behind, with the true poses as the VO 0.011 m); scale, height and flags are kept.
  // Why: the registrations fit the structure's points to the map, and the structure triangulated
  // along the VO's poses is turned against its cameras (synthetic street: up to 0.09 deg, mostly
  // roll) and bent by the depths of its thin-parallax points; the bundle lets the images say where
  // the points are and the map where they lie, and the camera follows its own sightings. The window
  // is the anchors' (window_m); one chunk over many anchors, not one bundle per anchor, because
  // each anchor's own window is one-sided at the drive's ends and its cameras' subsets (every 3rd
  // camera, or 3000 of the 7600 points) turned the camera by 0.04 deg more: the rotation wants all
  // the sightings. Synthetic 15 Hz street, the tests' / dense / 2 deg grade / sparse map: rotation
  // max 0.094 / 0.101 / 0.099 / 0.169 -> 0.043 / 0.045 / 0.040 / 0.080 deg; KITTI with the SIFT
  // structure: rotation max +0.02 to +0.05 deg (its yaw error is the truth's heading, README),
  // positions unchanged.
  bool map_bundle = true;
  double bundle_window_m = 40.0;
  int bundle_iterations = 10;  // Levenberg-Marquardt iterations per distance
  double bundle_chunk_m = 100.0;
  std::vector<double> bundle_distances_m = {0.5, 0.3};  // the registration's last levels
  double bundle_plane_sigma_m = 0.05;   // the map's planes (LiDAR range noise, a few cm)
  double bundle_huber_px = 1.0;         // SIFT keypoints: about a pixel
  double bundle_centre_sigma_m = 0.15;  // an ok anchor claims its place along the road to
                                        // 2 sigma = 0.3 m (max_along_sigma_m)
  // The map bundle also holds each window camera's roll (about its optical axis) near the one its
  // image's near-vertical line segments show (MeasureVertical, vertical_lines.h), within their
  // fit's standard error: the sightings and the map's planes leave a soft turn of the cameras
  // with the points sliding within their surfaces, where the bundle settled 0.1-0.2 deg off,
  // mostly in roll (README, "Where the map bundle's tilt ..."). The lines' pitch is not used: in
  // a camera looking along the road they are nearly parallel, and their convergence was 0.3-0.8
  // deg off on KITTI (trees, few facades), which moved the anchors.
  bool bundle_vertical_lines = true;
  VerticalLinesOptions vertical_lines;
  double min_inlier_share = 0.3;        // reliability: share of points within the finest distance
  double max_rms_m = 0.15;              // reliability: RMS residual of the inliers, metres
  double max_scale_change = 0.2;        // reliability: |scale / seed scale - 1|
  double min_along_information = 0.01;  // reliability: mean (n . road)^2 of the inliers
  // Reliability: translation sigma along the road, metres; an ok anchor claims its place along
  // the road to 2 sigma. Half the finest correspondence distance (0.3 m): the along-road profile
  // moves the fit in steps of it, so a claim below that is not verified by anything but the
  // Hessian's sigma, which is not calibrated (KITTI: 0.004 m against errors of RMS 0.08 m).
  double max_along_sigma_m = 0.15;
  double gnss_sigma_m = 3.0;            // horizontal GNSS standard deviation, metres
  double max_prior_sigmas = 4.0;        // reliability: offset from the GNSS at most this * sigma
  double max_height_offset_m = 1.0;     // reliability: |height above ground - camera height|
  double max_tilt_deg = 15.0;           // reliability: |pitch|, |roll| of the camera at most
  double heading_error_deg = 0.0;       // testing: perturb the prior heading uniformly in +-this
  uint64_t seed = 1;                    // seeds the heading perturbation
  int num_threads = 2;                  // frames anchored in parallel

  // Throws Error naming the first invalid field.
  void Check() const;
};

// The VO input of structure anchoring, in the trajectory's world frame.
struct VoStructure {
  std::vector<StampedPose> poses;  // world_from_cam, time order (timestamps = drive frame times)
  std::vector<VoPoint> points;
  // Focal length (pixels) of the camera whose normalised coordinates the points' sightings
  // (VoPoint::seen) are: their residuals in pixels. 0 when no point has sightings.
  double observation_focal_px = 0.0;
  struct Segment {
    int id = 0;
    frame_t first = kInvalidFrame;  // first and last posed frame
    frame_t last = kInvalidFrame;
  };
  std::vector<Segment> segments;  // from the trajectory's "# segment" comments (may be empty)

  // Segment of a frame number: the listed segment whose range holds it (0 when none are listed;
  // -1 for kInvalidFrame or a frame outside every listed range).
  int SegmentOf(frame_t frame) const;
  // Reads a TUM trajectory (`epiloc vo`) and its points file (VoPointsPath when
  // `points_path` is empty). Throws Error naming the file.
  static VoStructure Read(const std::string& trajectory_path, const std::string& points_path = "");
  // Poses read elsewhere (ORB-SLAM2/3, stella_vslam or KITTI poses: georef/trajectory_import.h)
  // with the points of `points_path` (none when empty: such a trajectory is anchored with the
  // drive's own SIFT structure, structure_sift.h) and the "# segment" comments of
  // `trajectory_path` (none: one segment). Throws Error naming the file.
  static VoStructure FromPoses(std::vector<StampedPose> poses,
                               const std::string& trajectory_path,
                               const std::string& points_path);
  // A stella_vslam map (io/stella_map.h, read from `path`): `poses` are its keyframes in its
  // order, put on the drive's clock and frames (georef's ImportTrajectory); its landmarks become
  // the points: first and last observing keyframe's frame, the count of observing keyframes, the
  // angle between the rays from those two. Keyframes on no drive frame do not count; a landmark
  // seen from fewer than two of the others is left out. One segment. Throws Error naming `path`
  // when `poses` do not match the map's keyframes.
  static VoStructure FromStellaMap(const StellaMap& map,
                                   std::vector<StampedPose> poses,
                                   const std::string& path);
  // The same from an odometry run in memory (VoOptions::keep_points).
  static VoStructure FromResult(const VoResult& result);
  // A copy whose poses carry the frame numbers of `drive`: the frame at each pose's time (within
  // 1 ms; a pose on no frame keeps its own). `pose_of` (optional) gets, per drive frame, the index
  // of its pose in `poses`, or -1.
  VoStructure OnFramesOf(const Drive& drive, std::vector<int>* pose_of = nullptr) const;
};

// An anchored camera as the consensus pass sees it (StructureAnchorOptions::consensus_radius_m).
struct PlacedAnchor {
  Similarity3 map_from_world;  // the similarity its pose implies (VO world -> map)
  Eigen::Vector3d vo_centre = Eigen::Vector3d::Zero();   // its camera centre in the VO world
  Eigen::Vector3d map_centre = Eigen::Vector3d::Zero();  // and in the map
  int segment = 0;                                       // its VO segment
  // The scale drift its fit applies (relative change of scale per metre of road, 0: none) and
  // the path it drifts along: the VO camera centres in order (shared by the anchors of a drive)
  // and the anchor's index among them (-1: not known; no drift applied).
  double scale_drift_per_m = 0.0;
  std::shared_ptr<const std::vector<Eigen::Vector3d>> path;
  int path_index = -1;

  // Where this anchor's fit places `other`'s camera centre in the map: its similarity applied to
  // other's VO centre moved by this anchor's drift along the path between them (ScaleDriftPath,
  // pivot = this anchor), as its own fit placed its structure; the similarity alone without a
  // drift or a shared path. A VO whose scale drifts by 3 % per 10 m (the shared KITTI drive's)
  // puts a camera 20 m away 0.6 m elsewhere without it.
  Eigen::Vector3d Placing(const PlacedAnchor& other) const;
};
// Per anchor, the distance along the road from its map centre to the median (per axis) of the
// placements of its VO centre (PlacedAnchor::Placing, with their drift) by the other anchors of
// its segment whose map centres lie within window_m / 2 of its own; nullopt with fewer than three
// of them. The road's direction: the VO path's tangent at the anchor turned by its similarity
// (the principal axis of the neighbours' map centres without a path).
std::vector<std::optional<double>> NeighbourDisagreement(const std::vector<PlacedAnchor>& anchors,
                                                         double window_m);
// Per anchor, the share of those placements (the same neighbours) that lie within claim_m of its
// map centre along the road; nullopt with fewer than three of them. A median that agrees with the
// anchor says little where the placements scatter over metres (a street whose registrations have
// several minima along it): most of them should agree.
std::vector<std::optional<double>> NeighbourAgreement(const std::vector<PlacedAnchor>& anchors,
                                                      double window_m,
                                                      double claim_m);
// Per anchor, the median (per axis) of the horizontal placements of its VO centre
// (PlacedAnchor::Placing) by the anchors of its segment whose map centres lie within window_m / 2
// of its own, itself included (StructureAnchorOptions::consensus_placement); nullopt with fewer
// than three of them.
std::vector<std::optional<Eigen::Vector2d>> ConsensusCentres(
    const std::vector<PlacedAnchor>& anchors, double window_m);
// Per anchor, the rotation consensus of its neighbours (StructureAnchorOptions::
// rotation_consensus): the chordal L1 median of the rotations of the similarities of the anchors
// of its segment whose map centres lie within window_m of its own (itself included; the anchors
// whose windows overlap its window). A median: an anchor turned by a wrong basin does not move it.
std::vector<Eigen::Quaterniond> ConsensusRotations(const std::vector<PlacedAnchor>& anchors,
                                                   double window_m);

// The median along_sigma_m of the anchors with a pose (infinity without any): how well the
// registrations fix them along the road, the direction a structure fixes least.
// AnchorDriveByStructureAuto keeps, of two structures, the one with the smaller.
double MedianAlongSigma(const AnchorDriveResult& result);

// How the VO's scale changes along the drive, from the ok anchors' scales (scale_m_per_unit):
// the least-squares slope of log(scale) over the distance travelled between the anchors' centres
// (horizontal chords in frame order). A monocular VO's scale wanders; a steady change of
// several percent per 100 m is the mark of a camera calibration error, often in the radial
// distortion (README, "What the drift responds to": the shared drive's VO loses 14 % over 60 m,
// and a radial term k1 of about +0.017 in its calibration takes that away; `epiloc
// calibrate-radial` finds the term from this trend). None with fewer than three ok anchors or
// less than 10 m between the first and the last (summed over the segments, below).
struct VoScaleTrend {
  int anchors = 0;           // ok anchors used
  int segments = 1;          // VO segments they lie in (each with two or more of them)
  double distance_m = 0.0;   // travelled from the first to the last of them, within segments
  double first_scale = NAN;  // the fitted line's scale at the first and at the last
  double last_scale = NAN;
  double percent_per_100m = 0.0;  // 100 m times the slope of log(scale), in percent
};
// With `segment_of` (frame -> the VO segment it belongs to, e.g. VoStructure::SegmentOf), each
// segment keeps its own scale (a VO restarted after a tracking loss starts with another) and one
// slope is fitted through all (the pooled within-segment least squares); segments with one ok
// anchor are left out.
std::optional<VoScaleTrend> ScaleTrendOfAnchors(
    const AnchorDriveResult& result, const std::function<int(frame_t)>& segment_of = nullptr);

// Anchors the selected frames of a drive (inputs.frames / inputs.every; photos_dir unused) by
// registering `vo`'s structure to the map. Frames without a VO pose are `lost`. Throws Error as
// AnchorDrive does. `progress` gets (frames done, frames).
AnchorDriveResult AnchorDriveByStructure(const AnchorInputs& inputs,
                                         const VoStructure& vo,
                                         const StructureAnchorOptions& options,
                                         const ProgressCallback& progress = nullptr);

// What AnchorDriveByStructureAuto chose.
struct StructureChoice {
  double first_sigma_m = INFINITY;        // MedianAlongSigma of the first pass with `vo`
  bool alternative_tried = false;         // the first not below max_along_sigma_m: the alternative
  double alternative_sigma_m = INFINITY;  // ... its first pass's
  bool alternative_kept = false;          // ... smaller: the alternative anchored the drive
  bool decided_by_finished_runs = false;  // equal first-pass medians: the sigmas above are the
                                          // finished runs'
  // The first fixed along the road, but its finished run has fewer ok anchors than
  // auto_min_ok_share of the frames: the alternative's finished run too (alternative_tried),
  // kept with more ok anchors.
  bool decided_by_ok = false;
  int first_ok = 0;        // ok anchors of the first's finished run (when not tried before)
  int alternative_ok = 0;  // ... and of the alternative's (decided_by_ok)
};

// `epiloc anchor --structure auto`: the first pass (every frame from the GNSS seed) with `vo`'s
// points; where they do not fix the anchors along the road better than the reliability limit
// (MedianAlongSigma at or above options.max_along_sigma_m: with the default limit, half the finest
// correspondence distance, the median anchor placed only to its along-road profile's resolution),
// also with `alternative()`'s structure (called then only: e.g. the SIFT structure,
// TriangulateAlongVo, which costs a pass over the drive's images), and the passes (drift,
// consensus, rotation consensus, the neighbours' check) only for the structure whose first pass has
// the smaller median sigma. Equal medians (the sigma comes in steps of half the finest
// correspondence distance) tell nothing: then both get the passes and the finished runs' medians
// decide (ties: `vo`). Where `vo`'s first pass fixes them but its finished run has fewer ok anchors
// than options.auto_min_ok_share of the frames, the alternative's finished run too, and the one
// with more ok anchors is kept (ties: `vo`). `choice` (optional) gets the figures.
AnchorDriveResult AnchorDriveByStructureAuto(const AnchorInputs& inputs,
                                             const VoStructure& vo,
                                             const std::function<VoStructure()>& alternative,
                                             const StructureAnchorOptions& options,
                                             const ProgressCallback& progress = nullptr,
                                             StructureChoice* choice = nullptr);

}  // namespace epiloc
