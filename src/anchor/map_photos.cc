#include "epiloc/anchor/map_photos.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "anchor_internal.h"
#include "epiloc/core/angles.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Bilinear sample at (x, y) in [0, cols - 1] x [0, rows - 1] (images of at least 2 x 2).
float SampleBilinear(const cv::Mat& grey, float x, float y) {
  const int x0 = std::min(static_cast<int>(std::floor(x)), grey.cols - 2);
  const int y0 = std::min(static_cast<int>(std::floor(y)), grey.rows - 2);
  const float ax = x - x0;
  const float ay = y - y0;
  const uint8_t* r0 = grey.ptr<uint8_t>(y0);
  const uint8_t* r1 = grey.ptr<uint8_t>(y0 + 1);
  return (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) +
         ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]);
}

}  // namespace

void MapPhotoOptions::Check() const {
  EPILOC_CHECK(max_views >= 1, "map photo options: max_views must be >= 1, got {}", max_views);
  EPILOC_CHECK(std::isfinite(max_view_distance_m) && max_view_distance_m > 0,
               "map photo options: max_view_distance_m must be > 0");
  EPILOC_CHECK(std::isfinite(max_view_angle_deg) && max_view_angle_deg > 0 &&
                   max_view_angle_deg <= 180,
               "map photo options: max_view_angle_deg must be in (0, 180]");
  EPILOC_CHECK(std::isfinite(depth_tolerance) && depth_tolerance >= 0 &&
                   std::isfinite(depth_tolerance_m) && depth_tolerance_m >= 0,
               "map photo options: depth tolerances must be >= 0");
}

MapPhotos::MapPhotos(const std::string& drive_dir,
                       const EnuFrame& map_frame,
                       const MapPhotoOptions& options)
    : options_(options), drive_(LoadDrive(drive_dir)), undistorter_(drive_.camera) {
  options_.Check();
  const PositionTrack* track = anchor_internal::OrientedTrack(drive_);
  if (track == nullptr) {
    Throw("{}: map photographs need the cameras' orientations (qw,qx,qy,qz in the ground truth "
          "or GNSS); the drive has none",
          drive_dir);
  }
  for (size_t i = 0; i < drive_.frames.size(); ++i) {
    const auto sample = track->Interpolate(drive_.frames[i].timestamp_s, drive_.max_gap_s);
    if (!sample || !sample->enu_from_cam) continue;
    poses_.push_back(
        {i, anchor_internal::MapFromSample(map_frame, sample->position, *sample->enu_from_cam)});
  }
  if (poses_.empty()) Throw("{}: no frame of the map-photo drive has a pose", drive_dir);
  reader_ = std::make_unique<FrameReader>(drive_);
}

std::vector<int> MapPhotos::Nearest(const Rigid3d& map_from_cam) const {
  const Eigen::Vector3d axis = map_from_cam.rotation * Eigen::Vector3d::UnitZ();
  const double min_cos = std::cos(options_.max_view_angle_deg * kDegToRad);
  std::vector<std::pair<double, int>> near;
  for (size_t i = 0; i < poses_.size(); ++i) {
    const Rigid3d& view = poses_[i].map_from_cam;
    const double distance = (view.translation - map_from_cam.translation).norm();
    if (distance > options_.max_view_distance_m) continue;
    if ((view.rotation * Eigen::Vector3d::UnitZ()).dot(axis) < min_cos) continue;
    near.emplace_back(distance, static_cast<int>(i));
  }
  const size_t keep = std::min(near.size(), static_cast<size_t>(options_.max_views));
  std::partial_sort(near.begin(), near.begin() + keep, near.end());
  std::vector<int> out;
  for (size_t k = 0; k < keep; ++k) out.push_back(near[k].second);
  return out;
}

cv::Mat MapPhotos::Read(int index) const {
  return undistorter_.Undistort(reader_->ReadGrey(poses_.at(index).frame_index));
}

MapPhotoCache::MapPhotoCache(const MapPhotos& photos,
                                 const PointCloud& local_map,
                                 const CloudRenderOptions& render_options)
    : photos_(photos), local_map_(local_map), render_options_(render_options) {
  render_options_.shading = RenderShading::kDepth;  // the photographs need geometry only
}

const MapPhoto& MapPhotoCache::Photo(int index) {
  auto it = views_.find(index);
  if (it != views_.end()) return it->second;
  MapPhoto view;
  view.grey = photos_.Read(index);
  view.cam_from_map = photos_.map_from_photo(index).Inverse();
  view.render = RenderCloud(local_map_, photos_.camera(), view.cam_from_map, render_options_);
  return views_.emplace(index, std::move(view)).first->second;
}

const MapPhoto& MapPhotoCache::Features(int index,
                                         const ImageMatchOptions& options,
                                         const LiftFunction& lift) {
  Photo(index);
  MapPhoto& view = views_.at(index);
  if (view.has_features) return view;
  const cv::Mat valid = view.render.depth > 0.f;
  const ImageFeatures all = ExtractFeatures(view.grey, options, valid);
  std::vector<int> rows;
  for (size_t i = 0; i < all.keypoints.size(); ++i) {
    Eigen::Vector3d x;
    if (!lift(view.render, photos_.camera(), view.cam_from_map, all.keypoints[i].pt, &x)) continue;
    rows.push_back(static_cast<int>(i));
    view.points.push_back(x);
  }
  view.features = SelectFeatures(all, rows);
  view.has_features = true;
  return view;
}

cv::Mat MapPhotoCache::Texture(const Camera& camera,
                               const Rigid3d& cam_from_map,
                               CloudRenderResult* render) {
  const MapPhotoOptions& options = photos_.options();
  const Camera& view_camera = photos_.camera();
  std::vector<const MapPhoto*> views;
  std::vector<Eigen::Matrix3f> rotations;
  std::vector<Eigen::Vector3f> translations;
  for (const int index : photos_.Nearest(cam_from_map.Inverse())) {
    const MapPhoto& view = Photo(index);
    const Rigid3d view_from_cam = view.cam_from_map * cam_from_map.Inverse();
    views.push_back(&view);
    rotations.push_back(view_from_cam.rotation.toRotationMatrix().cast<float>());
    translations.push_back(view_from_cam.translation.cast<float>());
  }
  const cv::Mat& depth = render->depth;
  cv::Mat grey(depth.size(), CV_8UC1, cv::Scalar(0));
  cv::Mat mask(depth.size(), CV_8UC1, cv::Scalar(0));
  const float fx = static_cast<float>(camera.fx), fy = static_cast<float>(camera.fy);
  const float cx = static_cast<float>(camera.cx), cy = static_cast<float>(camera.cy);
  const float vfx = static_cast<float>(view_camera.fx), vfy = static_cast<float>(view_camera.fy);
  const float vcx = static_cast<float>(view_camera.cx), vcy = static_cast<float>(view_camera.cy);
  const float rel = static_cast<float>(options.depth_tolerance);
  const float abs_m = static_cast<float>(options.depth_tolerance_m);
  const float max_x = static_cast<float>(view_camera.width - 1);
  const float max_y = static_cast<float>(view_camera.height - 1);
  cv::parallel_for_(cv::Range(0, depth.rows), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v) {
      const float* d_row = depth.ptr<float>(v);
      uint8_t* g_row = grey.ptr<uint8_t>(v);
      uint8_t* m_row = mask.ptr<uint8_t>(v);
      for (int u = 0; u < depth.cols; ++u) {
        const float d = d_row[u];
        if (d <= 0.f) continue;
        const Eigen::Vector3f x(d * (u - cx) / fx, d * (v - cy) / fy, d);
        for (size_t k = 0; k < views.size(); ++k) {
          const Eigen::Vector3f y = rotations[k] * x + translations[k];
          if (y.z() < 0.3f) continue;
          const float px = vfx * y.x() / y.z() + vcx;
          const float py = vfy * y.y() / y.z() + vcy;
          // Half a pixel of slack at the border (the pixel still lies on the image).
          if (!(px >= -0.5f && py >= -0.5f && px <= max_x + 0.5f && py <= max_y + 0.5f)) continue;
          const float sx = std::clamp(px, 0.f, max_x);
          const float sy = std::clamp(py, 0.f, max_y);
          const float seen = views[k]->render.depth.at<float>(static_cast<int>(std::lround(sy)),
                                                              static_cast<int>(std::lround(sx)));
          if (seen <= 0.f || std::abs(seen - y.z()) > rel * y.z() + abs_m) continue;
          g_row[u] = cv::saturate_cast<uint8_t>(SampleBilinear(views[k]->grey, sx, sy));
          m_row[u] = 255;
          break;
        }
      }
    }
  });
  render->image = grey;
  render->shading = RenderShading::kIntensity;
  return mask;
}

}  // namespace epiloc
