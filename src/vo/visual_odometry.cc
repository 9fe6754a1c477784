#include "epiloc/vo/visual_odometry.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>
#include <unordered_map>

#include <spdlog/spdlog.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "epiloc/core/statistics.h"
#include "vo_map.h"

namespace epiloc {
namespace {

// The state of one processed frame; its pose is kept relative to a reference keyframe so that
// it follows that keyframe's bundle adjustment.
struct FrameState {
  frame_t frame = kInvalidFrame;
  double timestamp_s = 0.0;
  VoFrameStatus status = VoFrameStatus::kInitializing;
  keyframe_t reference = kInvalidKeyframe;  // set when posed
  Rigid3d cam_from_reference;
  int segment = -1;
  int inliers = 0;
};

Eigen::Vector3d Centre(const Rigid3d& cam_from_world) {
  return -(cam_from_world.rotation.conjugate() * cam_from_world.translation);
}

}  // namespace

void VoOptions::Check() const {
  klt.Check();
  EPILOC_CHECK(init_min_flow_px > 0.0, "vo: init_min_flow_px must be > 0, got {}",
               init_min_flow_px);
  EPILOC_CHECK(init_max_frames >= 2, "vo: init_max_frames must be >= 2, got {}", init_max_frames);
  EPILOC_CHECK(max_error_px > 0.0, "vo: max_error_px must be > 0, got {}", max_error_px);
  EPILOC_CHECK(min_inliers >= 6, "vo: min_inliers must be >= 6, got {}", min_inliers);
  EPILOC_CHECK(keyframe_baseline_ratio > 0.0 && keyframe_min_baseline_ratio >= 0.0 &&
                   keyframe_min_baseline_ratio <= keyframe_baseline_ratio,
               "vo: keyframe baseline ratios must satisfy 0 <= min <= baseline, 0 < baseline");
  EPILOC_CHECK(keyframe_tracked_ratio > 0.0 && keyframe_tracked_ratio < 1.0,
               "vo: keyframe_tracked_ratio must be in (0, 1), got {}", keyframe_tracked_ratio);
  EPILOC_CHECK(keyframe_max_interval >= 1, "vo: keyframe_max_interval must be >= 1, got {}",
               keyframe_max_interval);
  EPILOC_CHECK(min_triangulation_parallax_deg >= 0.0,
               "vo: min_triangulation_parallax_deg must be >= 0, got {}",
               min_triangulation_parallax_deg);
  EPILOC_CHECK(ba_window >= 2, "vo: ba_window must be >= 2, got {}", ba_window);
  EPILOC_CHECK(ba_iterations >= 1, "vo: ba_iterations must be >= 1, got {}", ba_iterations);
  EPILOC_CHECK(global_ba_iterations >= 0, "vo: global_ba_iterations must be >= 0, got {}",
               global_ba_iterations);
  EPILOC_CHECK(huber_px > 0.0, "vo: huber_px must be > 0, got {}", huber_px);
  EPILOC_CHECK(num_threads >= 1, "vo: num_threads must be >= 1, got {}", num_threads);
}

class VisualOdometry::Impl {
 public:
  Impl(const Camera& camera, const VoOptions& options)
      : camera_(camera), options_(options), tracker_(options.klt), map_(MakeMapOptions()) {
    camera_.Check("vo camera");
    options_.Check();
    options_.two_view.focal_px = focal_px();
  }

  VoFrameStatus ProcessFrame(frame_t frame, double timestamp_s, const cv::Mat& image);
  void Finish();
  VoResult Result() const;

 private:
  double focal_px() const { return 0.5 * (camera_.fx + camera_.fy); }
  MapOptions MakeMapOptions() const {
    MapOptions m;
    m.max_error_px = options_.max_error_px;
    m.min_parallax_deg = options_.min_triangulation_parallax_deg;
    m.ba_window = options_.ba_window;
    m.keep_history = options_.global_ba_iterations > 0 || options_.keep_points;
    m.bundle = BundleOptions();
    m.bundle.focal_px = 0.5 * (camera_.fx + camera_.fy);
    m.bundle.huber_px = options_.huber_px;
    m.bundle.max_iterations = options_.ba_iterations;
    m.bundle.num_threads = options_.num_threads;
    return m;
  }
  Eigen::Vector2d Normalized(const Eigen::Vector2d& pixel) const {
    return camera_.HasDistortion() ? camera_.Unproject(pixel)
                                   : Eigen::Vector2d((pixel.x() - camera_.cx) / camera_.fx,
                                                     (pixel.y() - camera_.cy) / camera_.fy);
  }
  std::vector<std::pair<track_t, Eigen::Vector2d>> CurrentObservations() const {
    std::vector<std::pair<track_t, Eigen::Vector2d>> observations;
    observations.reserve(tracker_.features().size());
    for (const TrackedFeature& f : tracker_.features()) {
      observations.emplace_back(f.id, Normalized(f.pixel));
    }
    return observations;
  }
  Rigid3d PredictPose() const;
  std::unordered_map<track_t, Eigen::Vector2d> PredictPixels(const Rigid3d& cam_from_world) const;

  void StartInitialization(FrameState& state);
  void TryInitialize(FrameState& state);
  void TrackFrame(FrameState& state);
  bool NeedKeyframe(const Rigid3d& cam_from_world, int inliers) const;
  void MakeKeyframe(FrameState& state, const Rigid3d& cam_from_world);
  void SetPose(FrameState& state, keyframe_t reference, const Rigid3d& cam_from_world) const {
    state.reference = reference;
    state.cam_from_reference = cam_from_world * map_.keyframe(reference).cam_from_world.Inverse();
    state.segment = segment_;
  }
  Rigid3d PoseOf(const FrameState& state) const {
    return state.cam_from_reference * map_.keyframe(state.reference).cam_from_world;
  }
  std::optional<Rigid3d> PnpRansac(const std::vector<Eigen::Vector3d>& points,
                                   const std::vector<Eigen::Vector2d>& x) const;

  Camera camera_;
  VoOptions options_;
  KltTracker tracker_;
  VoMap map_;
  std::vector<FrameState> frames_;
  bool initializing_ = false;
  bool tracking_ = false;
  int segment_ = -1;
  keyframe_t segment_first_ = kInvalidKeyframe;
  // Initialisation: the reference frame's observations and the frames seen since.
  size_t reference_index_ = 0;
  std::unordered_map<track_t, std::pair<Eigen::Vector2d, Eigen::Vector2d>> reference_;  // x, pixel
  std::vector<std::pair<size_t, std::vector<std::pair<track_t, Eigen::Vector2d>>>> pending_;
  // Tracking: the last two poses (constant-velocity prediction).
  Rigid3d last_pose_, previous_pose_;
  keyframe_t last_keyframe_ = kInvalidKeyframe;
  int frames_since_keyframe_ = 0;
  // Joining the next segment after a loss.
  std::optional<Rigid3d> join_pose_;  // predicted cam_from_world of the lost frame
  double join_depth_ = 1.0;           // median depth of the last keyframe before the loss
  std::vector<double> join_scales_;   // per segment
  double ba_seconds_ = 0.0;
  double global_ba_seconds_ = 0.0;
  bool finished_ = false;
};

Rigid3d VisualOdometry::Impl::PredictPose() const {
  return (last_pose_ * previous_pose_.Inverse()) * last_pose_;
}

std::unordered_map<track_t, Eigen::Vector2d> VisualOdometry::Impl::PredictPixels(
    const Rigid3d& cam_from_world) const {
  std::unordered_map<track_t, Eigen::Vector2d> pixels;
  for (const TrackedFeature& f : tracker_.features()) {
    const MapTrack* track = map_.FindTrack(f.id);
    if (!track || !track->has_point) continue;
    const Eigen::Vector3d p = cam_from_world * track->point_in_world;
    if (p.z() <= 1e-6 * p.norm()) continue;
    pixels.emplace(f.id, camera_.Project(p));
  }
  return pixels;
}

VoFrameStatus VisualOdometry::Impl::ProcessFrame(frame_t frame,
                                                 double timestamp_s,
                                                 const cv::Mat& image) {
  EPILOC_CHECK(image.cols == camera_.width && image.rows == camera_.height,
               "vo: frame {} is {}x{}, the camera {}x{}", frame, image.cols, image.rows,
               camera_.width, camera_.height);
  EPILOC_CHECK(!finished_, "vo: frame {} after Finish()", frame);
  EPILOC_CHECK(frames_.empty() || timestamp_s >= frames_.back().timestamp_s,
               "vo: frame {} at {} s is before the previous frame", frame, timestamp_s);
  cv::Mat grey = image;
  if (image.type() == CV_8UC3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else {
    EPILOC_CHECK(image.type() == CV_8UC1, "vo: frame {} is not an 8-bit grey or BGR image", frame);
  }
  FrameState state;
  state.frame = frame;
  state.timestamp_s = timestamp_s;
  const std::unordered_map<track_t, Eigen::Vector2d> predicted =
      tracking_ ? PredictPixels(PredictPose()) : std::unordered_map<track_t, Eigen::Vector2d>();
  tracker_.Track(grey, predicted);
  if (tracking_) {
    TrackFrame(state);
  } else if (initializing_) {
    TryInitialize(state);
  } else {
    StartInitialization(state);
  }
  frames_.push_back(state);
  return state.status;
}

void VisualOdometry::Impl::StartInitialization(FrameState& state) {
  tracker_.Detect();
  reference_index_ = frames_.size();  // this frame's index once stored
  reference_.clear();
  for (const TrackedFeature& f : tracker_.features()) {
    reference_.emplace(f.id, std::make_pair(Normalized(f.pixel), f.pixel));
  }
  pending_.clear();
  initializing_ = true;
  tracking_ = false;
  if (state.status != VoFrameStatus::kLost) state.status = VoFrameStatus::kInitializing;
}

void VisualOdometry::Impl::TryInitialize(FrameState& state) {
  std::vector<Eigen::Vector2d> x1, x2;
  std::vector<track_t> ids;
  std::vector<double> flow;
  for (const TrackedFeature& f : tracker_.features()) {
    const auto it = reference_.find(f.id);
    if (it == reference_.end()) continue;
    ids.push_back(f.id);
    x1.push_back(it->second.first);
    x2.push_back(Normalized(f.pixel));
    flow.push_back((f.pixel - it->second.second).norm());
  }
  const size_t since = frames_.size() - reference_index_;
  state.status = VoFrameStatus::kInitializing;
  if (static_cast<int>(ids.size()) < options_.two_view.min_inliers ||
      static_cast<int>(since) > options_.init_max_frames) {
    StartInitialization(state);
    return;
  }
  pending_.emplace_back(frames_.size(), CurrentObservations());
  if (UpperMedian(flow) < options_.init_min_flow_px) return;
  TwoViewOptions two_view = options_.two_view;
  two_view.seed = options_.two_view.seed + static_cast<uint64_t>(frames_.size());
  const TwoViewResult result = EstimateTwoView(x1, x2, two_view);
  if (!result.ok) {
    spdlog::debug("vo: frame {}: no initialisation yet ({})", state.frame, result.failure);
    return;
  }

  // The map starts: the reference frame and this one are the segment's first keyframes.
  ++segment_;
  map_.ClearTracks();
  const FrameState& reference_state = frames_[reference_index_];
  Keyframe kf0;
  kf0.frame = reference_state.frame;
  kf0.timestamp_s = reference_state.timestamp_s;
  kf0.segment = segment_;
  for (const auto& [id, xp] : reference_) kf0.observations.emplace_back(id, xp.first);
  const keyframe_t first = map_.AddKeyframe(std::move(kf0));
  Keyframe kf1;
  kf1.frame = state.frame;
  kf1.timestamp_s = state.timestamp_s;
  kf1.segment = segment_;
  kf1.cam_from_world = result.cam2_from_cam1;
  kf1.observations = pending_.back().second;
  const keyframe_t second = map_.AddKeyframe(std::move(kf1));
  for (size_t i = 0; i < ids.size(); ++i) {
    if (!result.points_in_cam1[i]) continue;
    // A point with too little parallax has no usable depth; it stays a candidate for
    // triangulation from a later keyframe, as in TriangulateNew.
    if (ParallaxDeg(Rigid3d(), result.cam2_from_cam1, *result.points_in_cam1[i]) <
        options_.min_triangulation_parallax_deg) {
      continue;
    }
    MapTrack& track = map_.tracks()[ids[i]];
    track.point_in_world = *result.points_in_cam1[i];
    track.has_point = true;
  }
  segment_first_ = first;
  ba_seconds_ += map_.LocalBundle(segment_, segment_first_).seconds;
  // Unit: the baseline of the first two keyframes.
  const double baseline = Centre(map_.keyframe(second).cam_from_world).norm();
  if (baseline > 0.0) map_.TransformSegment(first, 1.0 / baseline, Rigid3d());
  double join_scale = 1.0;
  if (join_pose_) {
    // Put the segment where the lost one was heading, at the scene depth it had.
    const double depth = map_.DepthStats(first).first;
    join_scale = depth > 0.0 ? join_depth_ / depth : 1.0;
    map_.TransformSegment(first, join_scale, join_pose_->Inverse());
    join_pose_.reset();
  }
  join_scales_.push_back(join_scale);
  for (const keyframe_t id : {first, second}) {
    Keyframe& kf = map_.keyframe(id);
    std::tie(kf.median_depth, kf.tracked_points) = map_.DepthStats(id);
  }

  // Pose the frames in between against the new points.
  frames_[reference_index_].status = VoFrameStatus::kKeyframe;
  SetPose(frames_[reference_index_], first, map_.keyframe(first).cam_from_world);
  previous_pose_ = map_.keyframe(first).cam_from_world;
  for (size_t k = 0; k + 1 < pending_.size(); ++k) {
    std::vector<Eigen::Vector3d> points;
    std::vector<Eigen::Vector2d> x;
    for (const auto& [id, xn] : pending_[k].second) {
      const MapTrack* track = map_.FindTrack(id);
      if (!track || !track->has_point) continue;
      points.push_back(track->point_in_world);
      x.push_back(xn);
    }
    const MotionOnlyResult refined =
        RefineMotionOnly(previous_pose_, points, x, options_.max_error_px, MakeMapOptions().bundle);
    FrameState& between = frames_[pending_[k].first];
    if (refined.num_inliers < options_.min_inliers) continue;
    between.status = VoFrameStatus::kTracked;
    between.inliers = refined.num_inliers;
    SetPose(between, first, refined.cam_from_world);
    previous_pose_ = refined.cam_from_world;
  }
  state.status = VoFrameStatus::kKeyframe;
  last_pose_ = map_.keyframe(second).cam_from_world;
  SetPose(state, second, last_pose_);
  state.inliers = map_.keyframe(second).tracked_points;
  last_keyframe_ = second;
  frames_since_keyframe_ = 0;
  tracker_.Detect();
  std::unordered_map<track_t, bool> known;
  for (const auto& [id, x] : map_.keyframe(second).observations) known[id] = true;
  for (const auto& [id, x] : CurrentObservations()) {
    if (!known.count(id)) map_.AddObservation(second, id, x);
  }
  pending_.clear();
  reference_.clear();
  initializing_ = false;
  tracking_ = true;
  spdlog::debug("vo: segment {} initialised at frame {} ({} points, median parallax {:.2f} deg)",
                segment_, state.frame, result.num_triangulated, result.median_parallax_deg);
}

std::optional<Rigid3d> VisualOdometry::Impl::PnpRansac(
    const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector2d>& x) const {
  if (points.size() < 6) return std::nullopt;
  std::vector<cv::Point3d> object(points.size());
  std::vector<cv::Point2d> image(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    object[i] = {points[i].x(), points[i].y(), points[i].z()};
    image[i] = {x[i].x(), x[i].y()};
  }
  cv::UsacParams usac;
  usac.threshold = options_.max_error_px / focal_px();
  usac.confidence = 0.999;
  usac.maxIterations = 500;
  usac.randomGeneratorState = static_cast<int>(frames_.size() & 0x7fffffff);
  cv::Mat rvec, tvec, inliers;
  try {
    const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
    if (!cv::solvePnPRansac(object, image, eye, cv::noArray(), rvec, tvec, inliers, usac)) {
      return std::nullopt;
    }
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d re;
  Eigen::Vector3d te;
  cv::cv2eigen(r, re);
  cv::cv2eigen(tvec, te);
  return Rigid3d::FromMatrix(re, te);
}

void VisualOdometry::Impl::TrackFrame(FrameState& state) {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> x;
  std::vector<track_t> ids;
  for (const TrackedFeature& f : tracker_.features()) {
    const MapTrack* track = map_.FindTrack(f.id);
    if (!track || !track->has_point) continue;
    points.push_back(track->point_in_world);
    x.push_back(Normalized(f.pixel));
    ids.push_back(f.id);
  }
  const BundleOptions refine_options = MakeMapOptions().bundle;
  const Rigid3d predicted = PredictPose();
  MotionOnlyResult refined =
      RefineMotionOnly(predicted, points, x, options_.max_error_px, refine_options);
  if (refined.num_inliers < options_.min_inliers) {
    if (const auto ransac = PnpRansac(points, x)) {
      refined = RefineMotionOnly(*ransac, points, x, options_.max_error_px, refine_options);
    }
  }
  if (refined.num_inliers < options_.min_inliers) {
    spdlog::warn("vo: tracking lost at frame {} ({} of {} map points fit); re-initialising",
                 state.frame, refined.num_inliers, points.size());
    state.status = VoFrameStatus::kLost;
    join_pose_ = predicted;
    join_depth_ = map_.keyframe(last_keyframe_).median_depth;
    StartInitialization(state);
    return;
  }
  std::vector<track_t> outliers;
  for (size_t i = 0; i < ids.size(); ++i) {
    if (!refined.inliers[i]) outliers.push_back(ids[i]);
  }
  tracker_.Drop(outliers);
  state.inliers = refined.num_inliers;
  previous_pose_ = last_pose_;
  last_pose_ = refined.cam_from_world;
  ++frames_since_keyframe_;
  if (NeedKeyframe(last_pose_, refined.num_inliers)) {
    MakeKeyframe(state, last_pose_);
  } else {
    state.status = VoFrameStatus::kTracked;
    SetPose(state, last_keyframe_, last_pose_);
  }
}

bool VisualOdometry::Impl::NeedKeyframe(const Rigid3d& cam_from_world, int inliers) const {
  const Keyframe& last = map_.keyframe(last_keyframe_);
  const double baseline = (Centre(cam_from_world) - Centre(last.cam_from_world)).norm();
  const double ratio = baseline / std::max(1e-9, last.median_depth);
  if (ratio >= options_.keyframe_baseline_ratio) return true;
  if (ratio < options_.keyframe_min_baseline_ratio) return false;  // (nearly) standing still
  if (inliers < options_.keyframe_tracked_ratio * last.tracked_points) return true;
  if (inliers < 3 * options_.min_inliers) return true;
  return frames_since_keyframe_ >= options_.keyframe_max_interval;
}

void VisualOdometry::Impl::MakeKeyframe(FrameState& state, const Rigid3d& cam_from_world) {
  Keyframe kf;
  kf.frame = state.frame;
  kf.timestamp_s = state.timestamp_s;
  kf.segment = segment_;
  kf.cam_from_world = cam_from_world;
  kf.observations = CurrentObservations();
  const keyframe_t id = map_.AddKeyframe(std::move(kf));
  map_.TriangulateNew(id);
  ba_seconds_ += map_.LocalBundle(segment_, segment_first_).seconds;
  tracker_.Detect();
  std::unordered_map<track_t, bool> known;
  for (const auto& [track, x] : map_.keyframe(id).observations) known[track] = true;
  for (const auto& [track, x] : CurrentObservations()) {
    if (!known.count(track)) map_.AddObservation(id, track, x);
  }
  Keyframe& made = map_.keyframe(id);
  std::tie(made.median_depth, made.tracked_points) = map_.DepthStats(id);
  map_.Prune(id, tracker_.features());
  last_keyframe_ = id;
  frames_since_keyframe_ = 0;
  last_pose_ = made.cam_from_world;  // adjusted by the BA
  state.status = VoFrameStatus::kKeyframe;
  SetPose(state, id, last_pose_);
}

void VisualOdometry::Impl::Finish() {
  if (finished_) return;
  finished_ = true;
  if (options_.global_ba_iterations == 0) return;
  const std::vector<Keyframe>& keyframes = map_.keyframes();
  for (size_t i = 0; i < keyframes.size(); ++i) {
    if (i > 0 && keyframes[i].segment == keyframes[i - 1].segment) continue;
    const LocalBundleStats stats = map_.GlobalBundle(
        keyframes[i].segment, static_cast<keyframe_t>(i), options_.global_ba_iterations);
    global_ba_seconds_ += stats.seconds;
    spdlog::debug(
        "vo: global BA of segment {}: {} keyframes, {} points, {} observations ({} "
        "removed), {:.2f} s",
        keyframes[i].segment, stats.poses, stats.points, stats.observations,
        stats.removed_observations, stats.seconds);
  }
  ba_seconds_ += global_ba_seconds_;
}

VoResult VisualOdometry::Impl::Result() const {
  VoResult result;
  int64_t inliers = 0;
  for (const FrameState& state : frames_) {
    ++result.summary.frames;
    if (state.status == VoFrameStatus::kLost) ++result.summary.lost;
    if (state.reference == kInvalidKeyframe) continue;
    VoFramePose pose;
    pose.frame = state.frame;
    pose.timestamp_s = state.timestamp_s;
    pose.world_from_cam = PoseOf(state).Inverse();
    pose.segment = state.segment;
    pose.keyframe = state.status == VoFrameStatus::kKeyframe;
    pose.inliers = state.inliers;
    inliers += state.inliers;
    result.poses.push_back(pose);
    if (pose.keyframe) ++result.summary.keyframes;
    if (result.segments.empty() || result.segments.back().id != pose.segment) {
      VoSegment segment;
      segment.id = pose.segment;
      segment.first_frame = pose.frame;
      segment.join_scale = join_scales_[static_cast<size_t>(pose.segment)];
      result.segments.push_back(segment);
    }
    VoSegment& segment = result.segments.back();
    segment.last_frame = pose.frame;
    ++segment.num_poses;
    segment.num_keyframes += pose.keyframe ? 1 : 0;
  }
  if (options_.keep_points) {
    for (const MapTrack* track : map_.PointTracks()) {
      const Keyframe& first = map_.keyframe(track->observations.front().first);
      VoPoint point;
      point.point_in_world = track->point_in_world;
      point.segment = first.segment;
      point.first_frame = first.frame;
      point.last_frame = map_.keyframe(track->observations.back().first).frame;
      point.observations = static_cast<int>(track->observations.size());
      point.parallax_deg =
          ParallaxDeg(track->point_in_world, Centre(first.cam_from_world),
                      Centre(map_.keyframe(track->observations.back().first).cam_from_world));
      result.points.push_back(point);
    }
    std::sort(result.points.begin(), result.points.end(), [](const VoPoint& a, const VoPoint& b) {
      return std::tie(a.first_frame, a.last_frame, a.point_in_world.x()) <
             std::tie(b.first_frame, b.last_frame, b.point_in_world.x());
    });
  }
  result.summary.posed = static_cast<int64_t>(result.poses.size());
  result.summary.mean_inliers =
      result.poses.empty() ? 0.0 : static_cast<double>(inliers) / result.poses.size();
  result.summary.ba_seconds = ba_seconds_;
  result.summary.global_ba_seconds = global_ba_seconds_;
  return result;
}

VisualOdometry::VisualOdometry(const Camera& camera, const VoOptions& options)
    : impl_(std::make_unique<Impl>(camera, options)) {}
VisualOdometry::~VisualOdometry() = default;

VoFrameStatus VisualOdometry::ProcessFrame(frame_t frame,
                                           double timestamp_s,
                                           const cv::Mat& image) {
  return impl_->ProcessFrame(frame, timestamp_s, image);
}

void VisualOdometry::Finish() { impl_->Finish(); }

VoResult VisualOdometry::Result() const { return impl_->Result(); }

double ParallaxDeg(const Eigen::Vector3d& point,
                   const Eigen::Vector3d& first_centre,
                   const Eigen::Vector3d& last_centre) {
  const Eigen::Vector3d a = point - first_centre, b = point - last_centre;
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

}  // namespace epiloc
