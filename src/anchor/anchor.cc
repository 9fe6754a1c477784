#include "epiloc/anchor/anchor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <optional>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "anchor_internal.h"
#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// One rendering of the map at a pose, matched and solved.
struct Attempt {
  bool covered = false;  // the rendering filled enough of the view
  double coverage = 0.0;
  int num_matches = 0;
  PnpResult pnp;
  Rigid3d map_from_cam;  // the solved pose when pnp.success
  std::string message;   // why there is no pose
};

bool BetterAttempt(const Attempt& a, const Attempt& b) {
  if (a.pnp.success != b.pnp.success) return a.pnp.success;
  if (a.pnp.num_inliers != b.pnp.num_inliers) return a.pnp.num_inliers > b.pnp.num_inliers;
  return a.pnp.rmse_px < b.pnp.rmse_px;
}

// The 3-D point behind a rendered feature. The z-buffer keeps the nearest of several noisy
// points and a splat has one depth over its whole square, so the depth of the pixel alone is
// biased towards the camera (by about the map's range noise) and stepped on oblique surfaces.
// Instead, the map points whose splats won the pixels within lift_radius_px are taken, those of
// the front surface kept (depth within max_depth_step of the nearest, plus 0.1 m), a plane
// fitted to them (least squares), and the pixel's ray intersected with it. Refused at depth
// edges (the 3x3 depths around the pixel spread more than the front-surface tolerance), with
// fewer than 6 front points, or where the ray grazes the plane (then the depth of the points'
// centroid along the ray is used if they are compact in depth).
bool LiftOnLocalPlane(const CloudRenderResult& render,
                      const Camera& camera,
                      const Rigid3d& cam_from_map,
                      const PointCloud& map,
                      const cv::Point2f& pixel,
                      int lift_radius_px,
                      double max_depth_step,
                      Eigen::Vector3d* point) {
  const int u = static_cast<int>(std::lround(pixel.x));
  const int v = static_cast<int>(std::lround(pixel.y));
  const int r = std::max(1, lift_radius_px);
  if (u < r || v < r || u >= render.depth.cols - r || v >= render.depth.rows - r) return false;
  float lo = INFINITY, hi = 0.f;
  for (int dv = -1; dv <= 1; ++dv) {
    const float* row = render.depth.ptr<float>(v + dv);
    for (int du = -1; du <= 1; ++du) {
      const float d = row[u + du];
      if (d <= 0.f) return false;
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  }
  const double tolerance = max_depth_step * lo + 0.1;
  if (hi - lo > tolerance) return false;

  std::vector<int32_t> indices;
  indices.reserve((2 * r + 1) * (2 * r + 1));
  for (int dv = -r; dv <= r; ++dv) {
    const int32_t* row = render.point_index.ptr<int32_t>(v + dv);
    for (int du = -r; du <= r; ++du) {
      if (row[u + du] >= 0) indices.push_back(row[u + du]);
    }
  }
  std::sort(indices.begin(), indices.end());
  indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
  std::vector<Eigen::Vector3d> front;
  front.reserve(indices.size());
  for (const int32_t i : indices) {
    const Eigen::Vector3d x = cam_from_map * map.positions[i].cast<double>();
    if (x.z() > 0 && x.z() <= lo + tolerance) front.push_back(x);
  }
  if (front.size() < 6) return false;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& x : front) centroid += x;
  centroid /= static_cast<double>(front.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& x : front) scatter += (x - centroid) * (x - centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  const Eigen::Vector3d normal = eigen.eigenvectors().col(0);
  const Eigen::Vector2d n = camera.Unproject(Eigen::Vector2d(pixel.x, pixel.y));
  const Eigen::Vector3d ray(n.x(), n.y(), 1.0);
  const double along = normal.dot(ray) / ray.norm();
  // A plane needs spread in two directions (not a line of points) and a ray not grazing it.
  const bool planar = eigen.eigenvalues()(1) > 4.0 * eigen.eigenvalues()(0) + 1e-12;
  double depth;
  if (planar && std::abs(along) > 0.2) {
    depth = normal.dot(centroid) / normal.dot(ray);
  } else {
    depth = centroid.z();
  }
  if (!(depth > 0) || std::abs(depth - 0.5 * (lo + hi)) > tolerance) return false;
  *point = cam_from_map.Inverse() * (depth * ray);
  return true;
}

Attempt TryPose(const ImageFeatures& frame,
                const Camera& camera,
                const PointCloud& map,
                const Rigid3d& map_from_cam,
                double search_radius_px,
                double splat_size_m,
                const AnchorOptions& options) {
  Attempt attempt;
  const Rigid3d cam_from_map = map_from_cam.Inverse();
  CloudRenderOptions render_options = options.render;
  render_options.splat_size_m = splat_size_m;
  render_options.num_threads = 1;  // frames run in parallel
  const CloudRenderResult render = RenderCloud(map, camera, cam_from_map, render_options);
  const cv::Mat valid = render.depth > 0.f;
  attempt.coverage = static_cast<double>(cv::countNonZero(valid)) / valid.total();
  if (attempt.coverage < options.min_coverage) {
    attempt.message = fmt::format("the map fills {:.1f}% of the view (< {:.1f}%)",
                                  100.0 * attempt.coverage, 100.0 * options.min_coverage);
    return attempt;
  }
  attempt.covered = true;
  cv::Mat grey = render.image;
  if (grey.channels() == 3) cv::cvtColor(render.image, grey, cv::COLOR_BGR2GRAY);
  cv::Mat mask = valid;
  if (options.erode_px > 0) {
    cv::erode(valid, mask,
              cv::getStructuringElement(cv::MORPH_RECT,
                                        cv::Size(2 * options.erode_px + 1, 2 * options.erode_px + 1)));
  }
  const ImageFeatures rendered = ExtractFeatures(grey, options.matching, mask);
  // Frame features where the map cannot be (sky, the upper scene a LiDAR does not reach, beyond
  // its range) have no counterpart and only crowd the ratio test: keep those within
  // frame_margin_px of the rendered area.
  cv::Mat near_map;
  cv::dilate(valid, near_map,
             cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * options.frame_margin_px + 1,
                                                                2 * options.frame_margin_px + 1)));
  std::vector<int> frame_rows;
  for (size_t i = 0; i < frame.keypoints.size(); ++i) {
    const cv::Point2f& p = frame.keypoints[i].pt;
    const int u = std::clamp(static_cast<int>(std::lround(p.x)), 0, near_map.cols - 1);
    const int v = std::clamp(static_cast<int>(std::lround(p.y)), 0, near_map.rows - 1);
    if (near_map.at<uint8_t>(v, u) == 0) continue;
    frame_rows.push_back(static_cast<int>(i));
    if (static_cast<int>(frame_rows.size()) >= options.max_frame_features) break;  // strongest first
  }
  const ImageFeatures frame_near = SelectFeatures(frame, frame_rows);
  ImageMatchOptions match_options = options.matching;
  match_options.search_radius_px = search_radius_px;
  const ImageMatches matches = MatchFeatures(frame_near, rendered, match_options);
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  for (size_t k = 0; k < matches.frame_index.size(); ++k) {
    Eigen::Vector3d x;
    if (!LiftOnLocalPlane(render, camera, cam_from_map, map,
                          rendered.keypoints[matches.render_index[k]].pt, options.lift_radius_px,
                          options.max_depth_step, &x)) {
      continue;
    }
    const cv::Point2f& p = frame_near.keypoints[matches.frame_index[k]].pt;
    pixels.emplace_back(p.x, p.y);
    points.push_back(x);
  }
  attempt.num_matches = static_cast<int>(pixels.size());
  attempt.pnp = EstimateAbsolutePose(pixels, points, camera, options.pnp);
  if (!attempt.pnp.success) {
    attempt.message = fmt::format("{} matches ({} after the ratio test): {}", matches.num_geometric,
                                  matches.num_ratio, attempt.pnp.message);
    return attempt;
  }
  attempt.map_from_cam = attempt.pnp.cam_from_world.Inverse();
  return attempt;
}

// Matches the frame against survey photographs of the map (map_photos.h) and solves PnP on
// their lifted features. With `guide`, each lifted point is first projected into the frame at
// that pose and frame features are matched only to points predicted within guided_radius_px.
Attempt TryPhotos(const ImageFeatures& frame,
                 const Camera& camera,
                 MapPhotoCache* cache,
                 const std::vector<int>& views,
                 const Rigid3d* guide,
                 const AnchorOptions& options,
                 const LiftFunction& lift) {
  Attempt attempt;
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  int num_ratio = 0, num_geometric = 0;
  ImageMatchOptions match_options = options.matching;
  match_options.search_radius_px = guide != nullptr ? options.guided_radius_px : 0.0;
  for (const int index : views) {
    const MapPhoto& view = cache->Features(index, options.matching, lift);
    attempt.coverage = std::max(attempt.coverage,
                                static_cast<double>(cv::countNonZero(view.render.depth > 0.f)) /
                                    static_cast<double>(view.render.depth.total()));
    // Guided: the photograph's features placed where their points project at the guide pose.
    std::vector<int> rows;
    std::vector<cv::Point2f> projected;
    if (guide != nullptr) {
      const Rigid3d cam_from_map = guide->Inverse();
      for (size_t i = 0; i < view.points.size(); ++i) {
        const Eigen::Vector3d x = cam_from_map * view.points[i];
        if (x.z() <= 0.1) continue;
        const Eigen::Vector2d p = camera.Project(x);
        if (p.x() < 0 || p.y() < 0 || p.x() > camera.width - 1 || p.y() > camera.height - 1) {
          continue;
        }
        rows.push_back(static_cast<int>(i));
        projected.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
      }
    } else {
      rows.resize(view.points.size());
      std::iota(rows.begin(), rows.end(), 0);
    }
    ImageFeatures reference = SelectFeatures(view.features, rows);
    for (size_t k = 0; k < projected.size(); ++k) reference.keypoints[k].pt = projected[k];
    if (reference.keypoints.size() < 2) continue;
    const ImageMatches matches = MatchFeatures(frame, reference, match_options);
    num_ratio += matches.num_ratio;
    num_geometric += matches.num_geometric;
    for (size_t k = 0; k < matches.frame_index.size(); ++k) {
      const cv::Point2f& p = frame.keypoints[matches.frame_index[k]].pt;
      pixels.emplace_back(p.x, p.y);
      points.push_back(view.points[rows[matches.render_index[k]]]);
    }
  }
  attempt.covered = attempt.coverage >= options.min_coverage;
  if (!attempt.covered) {
    attempt.message = fmt::format("the map fills {:.1f}% of the photographs (< {:.1f}%)",
                                  100.0 * attempt.coverage, 100.0 * options.min_coverage);
    return attempt;
  }
  attempt.num_matches = static_cast<int>(pixels.size());
  attempt.pnp = EstimateAbsolutePose(pixels, points, camera, options.pnp);
  if (!attempt.pnp.success) {
    attempt.message = fmt::format("{} matches ({} after the ratio test): {}", num_geometric,
                                  num_ratio, attempt.pnp.message);
    return attempt;
  }
  attempt.map_from_cam = attempt.pnp.cam_from_world.Inverse();
  return attempt;
}

// The features reordered by decreasing detector response.
ImageFeatures StrongestFirst(const ImageFeatures& features) {
  std::vector<int> order(features.keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return features.keypoints[a].response > features.keypoints[b].response;
  });
  return SelectFeatures(features, order);
}

using anchor_internal::PitchRollDeg;

// The reliability checks of a solved pose: "" or why it is rejected.
std::string Unreliable(const AnchorResult& r, const AnchorOptions& options) {
  if (r.num_inliers < options.min_inliers) {
    return fmt::format("{} inliers, fewer than {}", r.num_inliers, options.min_inliers);
  }
  if (r.rmse_px > options.max_rmse_px) {
    return fmt::format("reprojection RMSE {:.2f} px above {:.2f} px", r.rmse_px,
                       options.max_rmse_px);
  }
  const double max_offset = options.max_prior_sigmas * options.gnss_sigma_m;
  if (r.prior_offset_m > max_offset) {
    return fmt::format("{:.1f} m from the GNSS prior, more than {:.0f} sigma ({:.1f} m)",
                       r.prior_offset_m, options.max_prior_sigmas, max_offset);
  }
  if (std::isfinite(r.height_above_ground_m) &&
      std::abs(r.height_above_ground_m - options.prior.camera_height_m) >
          options.max_height_offset_m) {
    return fmt::format("camera {:.2f} m above the map's ground, expected {:.2f} +- {:.2f} m",
                       r.height_above_ground_m, options.prior.camera_height_m,
                       options.max_height_offset_m);
  }
  const auto [pitch, roll] = PitchRollDeg(r.map_from_cam.rotation.toRotationMatrix());
  if (std::abs(pitch) > options.max_tilt_deg || std::abs(roll) > options.max_tilt_deg) {
    return fmt::format("camera tilted (pitch {:.1f}, roll {:.1f} deg; at most {:.1f})", pitch,
                       roll, options.max_tilt_deg);
  }
  return "";
}

}  // namespace

std::string AnchorStatusName(AnchorStatus status) {
  switch (status) {
    case AnchorStatus::kOk:
      return "ok";
    case AnchorStatus::kRejected:
      return "rejected";
    case AnchorStatus::kLost:
      return "lost";
    case AnchorStatus::kNoCoverage:
      return "no_coverage";
    case AnchorStatus::kNoPrior:
      return "no_prior";
  }
  return "?";
}

RenderShading ParseRenderShading(const std::string& name) {
  if (name == "auto") return RenderShading::kAuto;
  if (name == "intensity") return RenderShading::kIntensity;
  if (name == "colour" || name == "color") return RenderShading::kColour;
  if (name == "depth") return RenderShading::kDepth;
  Throw("unknown shading '{}' (known: auto, intensity, colour, depth)", name);
}

PnpOptions AnchorOptions::WidePnp() {
  PnpOptions pnp;
  pnp.max_reprojection_px = 4.0;
  return pnp;
}

void AnchorOptions::Check() const {
  prior.Check();
  candidates.Check();
  matching.Check();
  pnp.Check();
  render.Check();
  EPILOC_CHECK(refine_rounds >= 0, "--refine-rounds must be >= 0, got {}", refine_rounds);
  EPILOC_CHECK(std::isfinite(guided_radius_px) && guided_radius_px >= 0,
               "anchor options: guided_radius_px must be >= 0");
  EPILOC_CHECK(std::isfinite(converged_m) && converged_m >= 0 && std::isfinite(converged_deg) &&
                   converged_deg >= 0,
               "anchor options: convergence thresholds must be >= 0");
  EPILOC_CHECK(std::isfinite(load_radius_m) && load_radius_m > 0,
               "anchor options: load_radius_m must be > 0, got {}", load_radius_m);
  EPILOC_CHECK(min_coverage >= 0 && min_coverage <= 1,
               "anchor options: min_coverage must be in [0, 1], got {}", min_coverage);
  EPILOC_CHECK(std::isfinite(max_depth_step) && max_depth_step > 0,
               "anchor options: max_depth_step must be > 0");
  EPILOC_CHECK(erode_px >= 0, "anchor options: erode_px must be >= 0");
  EPILOC_CHECK(frame_margin_px >= 0, "anchor options: frame_margin_px must be >= 0");
  EPILOC_CHECK(max_frame_features >= 1, "anchor options: max_frame_features must be >= 1");
  EPILOC_CHECK(std::isfinite(refine_splat_size_m) && refine_splat_size_m > 0,
               "anchor options: refine_splat_size_m must be > 0, got {}", refine_splat_size_m);
  EPILOC_CHECK(lift_radius_px >= 1 && lift_radius_px <= 16,
               "anchor options: lift_radius_px must be in [1, 16], got {}", lift_radius_px);
  EPILOC_CHECK(min_inliers >= pnp.min_inliers, "--min-inliers must be >= {} (PnP), got {}",
               pnp.min_inliers, min_inliers);
  EPILOC_CHECK(std::isfinite(max_rmse_px) && max_rmse_px > 0, "--max-rmse must be > 0 px");
  EPILOC_CHECK(std::isfinite(gnss_sigma_m) && gnss_sigma_m > 0, "--gnss-sigma must be > 0 m");
  EPILOC_CHECK(std::isfinite(max_prior_sigmas) && max_prior_sigmas > 0,
               "anchor options: max_prior_sigmas must be > 0");
  EPILOC_CHECK(std::isfinite(max_height_offset_m) && max_height_offset_m > 0,
               "anchor options: max_height_offset_m must be > 0");
  EPILOC_CHECK(std::isfinite(max_tilt_deg) && max_tilt_deg > 0,
               "anchor options: max_tilt_deg must be > 0");
  EPILOC_CHECK(std::isfinite(heading_error_deg) && heading_error_deg >= 0 &&
                   heading_error_deg <= 180,
               "--heading-error-deg must be in [0, 180], got {}", heading_error_deg);
  EPILOC_CHECK(num_threads >= 1, "--threads must be >= 1, got {}", num_threads);
  photometric_options.Check();
  EPILOC_CHECK(std::isfinite(max_photometric_shift_m) && max_photometric_shift_m > 0,
               "anchor options: max_photometric_shift_m must be > 0");
}

PosePrior RotatePriorHeading(const PosePrior& prior, double delta_deg) {
  PosePrior out = prior;
  out.heading_deg = std::fmod(prior.heading_deg + delta_deg + 360.0, 360.0);
  out.map_from_cam = Rigid3d::FromMatrix(MapFromCamRotation(out.heading_deg), prior.position_in_map);
  return out;
}

AnchorResult AnchorFrame(const cv::Mat& image,
                         const Camera& camera,
                         const PointCloud& local_map,
                         const EnuFrame& map_frame,
                         const PosePrior& prior,
                         const AnchorOptions& options,
                         const MapPhotos* photos) {
  const auto start = std::chrono::steady_clock::now();
  options.Check();
  EPILOC_CHECK(image.cols == camera.width && image.rows == camera.height,
               "AnchorFrame: image size {}x{} differs from the camera's {}x{}", image.cols,
               image.rows, camera.width, camera.height);
  AnchorResult result;
  result.frame = prior.frame;
  result.timestamp_s = prior.timestamp_s;
  result.has_prior = true;
  result.prior = prior;
  const auto finish = [&](AnchorResult r) {
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return r;
  };

  cv::Mat grey = image;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  ImageMatchOptions frame_options = options.matching;
  frame_options.max_features = 0;  // all: each candidate keeps the strongest near its map
  const ImageFeatures frame = StrongestFirst(ExtractFeatures(grey, frame_options));
  result.num_frame_features = static_cast<int>(frame.keypoints.size());

  // Candidates (frames differ in their seed so the random candidates do too).
  const std::vector<Rigid3d> candidates = GenerateCandidates(
      prior, options.candidates,
      options.seed * 1000003ULL + static_cast<uint64_t>(std::max<frame_t>(prior.frame, 0)));
  // With map photographs (map_photos.h), a candidate is the photograph nearest to it (each
  // photograph once) and refinement matches the photographs nearest to the solved pose, guided
  // by it; otherwise candidates and refinement render the map.
  std::optional<MapPhotoCache> photo_cache;
  CloudRenderOptions photo_render = options.render;
  photo_render.num_threads = 1;
  if (photos) photo_cache.emplace(*photos, local_map, photo_render);
  const LiftFunction lift = [&](const CloudRenderResult& render, const Camera& view_camera,
                                const Rigid3d& cam_from_map, const cv::Point2f& pixel,
                                Eigen::Vector3d* x) {
    return LiftOnLocalPlane(render, view_camera, cam_from_map, local_map, pixel,
                            options.lift_radius_px, options.max_depth_step, x);
  };
  ImageFeatures frame_top;  // the strongest frame features, for matching photographs
  if (photos) {
    std::vector<int> rows(std::min<size_t>(options.max_frame_features, frame.keypoints.size()));
    std::iota(rows.begin(), rows.end(), 0);
    frame_top = SelectFeatures(frame, rows);
  }
  std::vector<int> tried_views;
  // Where no photograph looks the same way near the pose (a survey driven the other way, a gap),
  // the map is rendered instead.
  const auto attempt_at = [&](const Rigid3d& pose, bool guided) -> std::optional<Attempt> {
    std::vector<int> views;
    if (photo_cache) views = photos->Nearest(pose);
    if (views.empty()) {
      return TryPose(frame, camera, local_map, pose, guided ? options.guided_radius_px : 0.0,
                     guided ? std::min(options.render.splat_size_m, options.refine_splat_size_m)
                            : options.render.splat_size_m,
                     options);
    }
    if (!guided) {
      views.resize(1);
      if (std::count(tried_views.begin(), tried_views.end(), views[0]) > 0) return std::nullopt;
      tried_views.push_back(views[0]);
    }
    return TryPhotos(frame_top, camera, &*photo_cache, views, guided ? &pose : nullptr, options,
                     lift);
  };

  Attempt best;
  best.message = "no candidate";
  bool any_covered = false;
  double max_coverage = 0.0;
  for (size_t c = 0; c < candidates.size(); ++c) {
    std::optional<Attempt> attempt = attempt_at(candidates[c], false);
    if (!attempt) continue;
    any_covered = any_covered || attempt->covered;
    max_coverage = std::max(max_coverage, attempt->coverage);
    if (c == 0 || BetterAttempt(*attempt, best)) {
      best = std::move(*attempt);
      result.best_candidate = static_cast<int>(c);
    }
  }
  if (!any_covered) {
    result.status = AnchorStatus::kNoCoverage;
    result.message = fmt::format(
        "the map does not cover the view: its rendering fills at most {:.1f}% of the image "
        "(< {:.1f}%)",
        100.0 * max_coverage, 100.0 * options.min_coverage);
    result.coverage = max_coverage;
    return finish(result);
  }
  if (!best.pnp.success) {
    result.status = AnchorStatus::kLost;
    result.message = best.message;
    result.num_matches = best.num_matches;
    result.coverage = best.coverage;
    return finish(result);
  }

  for (int round = 0; round < options.refine_rounds; ++round) {
    Attempt refined = *attempt_at(best.map_from_cam, true);
    if (!refined.pnp.success) break;
    const double moved_m = (refined.map_from_cam.translation - best.map_from_cam.translation).norm();
    const double turned_deg =
        RotationDifferenceDeg(refined.map_from_cam.rotation, best.map_from_cam.rotation);
    best = std::move(refined);
    ++result.rounds;
    if (moved_m < options.converged_m && turned_deg < options.converged_deg) break;
  }

  if (options.photometric) {
    CloudRenderOptions render_options = options.render;
    render_options.num_threads = 1;
    const PhotometricResult photometric =
        RefinePhotometric(grey, camera, local_map, best.map_from_cam.Inverse(), render_options,
                          options.photometric_options);
    const Rigid3d refined = photometric.cam_from_world.Inverse();
    const double shift = (refined.translation - best.map_from_cam.translation).norm();
    result.photometric_ncc = photometric.ncc;
    result.photometric_shift_m = shift;
    if (photometric.success && shift <= options.max_photometric_shift_m) {
      best.map_from_cam = refined;
    }
  }

  result.has_pose = true;
  result.map_from_cam = best.map_from_cam;
  result.num_matches = best.num_matches;
  result.num_inliers = best.pnp.num_inliers;
  result.rmse_px = best.pnp.rmse_px;
  result.coverage = best.coverage;
  const Eigen::Vector3d centre = best.map_from_cam.translation;
  result.position = map_frame.ToGeodetic(centre);
  result.enu_from_cam = Eigen::Quaterniond(
      map_frame.EnuFromLocalEnu(result.position).transpose() *
      best.map_from_cam.rotation.toRotationMatrix()).normalized();
  result.prior_offset_m = (centre - prior.position_in_map).head<2>().norm();
  if (const auto ground = GroundHeight(local_map, centre.head<2>(), options.prior)) {
    result.height_above_ground_m = centre.z() - *ground;
  }
  result.message = Unreliable(result, options);
  result.status = result.message.empty() ? AnchorStatus::kOk : AnchorStatus::kRejected;
  return finish(result);
}

}  // namespace epiloc
