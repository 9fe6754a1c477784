// Occlusion-aware colouring of a map from camera frames (build_map.h).
#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "anchor_internal.h"
#include "epiloc/anchor/build_map.h"
#include "epiloc/camera/undistorter.h"
#include "epiloc/core/error.h"
#include "epiloc/core/parallel.h"
#include "epiloc/io/frame_reader.h"

namespace epiloc {
namespace {

using anchor_internal::MapFromSample;

// Per point: the running sum (average) or the best sample (closest).
struct ColourAccumulator {
  std::vector<std::array<float, 3>> sum;  // RGB
  std::vector<uint32_t> count;            // samples summed (kClosest: 0 or 1)
  std::vector<float> best_distance_m;     // kClosest: distance of the frame that set the colour
};

std::array<float, 3> SampleBilinear(const cv::Mat& bgr, double u, double v) {
  const int u0 = static_cast<int>(std::floor(u));
  const int v0 = static_cast<int>(std::floor(v));
  const float a = static_cast<float>(u - u0);
  const float b = static_cast<float>(v - v0);
  const cv::Vec3b& p00 = bgr.at<cv::Vec3b>(v0, u0);
  const cv::Vec3b& p01 = bgr.at<cv::Vec3b>(v0, u0 + 1);
  const cv::Vec3b& p10 = bgr.at<cv::Vec3b>(v0 + 1, u0);
  const cv::Vec3b& p11 = bgr.at<cv::Vec3b>(v0 + 1, u0 + 1);
  std::array<float, 3> rgb;
  for (int c = 0; c < 3; ++c) {
    const float top = (1 - a) * p00[c] + a * p01[c];
    const float bottom = (1 - a) * p10[c] + a * p11[c];
    rgb[2 - c] = (1 - b) * top + b * bottom;  // BGR -> RGB
  }
  return rgb;
}

// An image pyramid sampled like a mipmap: a point whose footprint covers n pixels takes the
// colour of level log2(n), blended between the two nearest levels, so a far-away frame and a
// near one give the point the same (area-averaged) colour instead of an aliased pixel.
class MipImage {
 public:
  MipImage(const cv::Mat& bgr, int levels) {
    levels_.push_back(bgr);
    for (int l = 1; l < levels && levels_.back().cols >= 8 && levels_.back().rows >= 8; ++l) {
      cv::Mat down;
      cv::pyrDown(levels_.back(), down);
      levels_.push_back(down);
    }
  }

  // Colour at full-resolution pixel (u, v) for a footprint of `footprint_px` pixels.
  std::array<float, 3> Sample(double u, double v, double footprint_px) const {
    const double level = std::clamp(std::log2(std::max(footprint_px, 1.0)), 0.0,
                                    static_cast<double>(levels_.size() - 1));
    const int l0 = static_cast<int>(std::floor(level));
    const int l1 = std::min(l0 + 1, static_cast<int>(levels_.size()) - 1);
    const float w = static_cast<float>(level - l0);
    std::array<float, 3> a = SampleLevel(l0, u, v);
    if (w > 0 && l1 != l0) {
      const std::array<float, 3> b = SampleLevel(l1, u, v);
      for (int c = 0; c < 3; ++c) a[c] = (1 - w) * a[c] + w * b[c];
    }
    return a;
  }

 private:
  std::array<float, 3> SampleLevel(int level, double u, double v) const {
    const cv::Mat& image = levels_[level];
    const double s = 1.0 / (1 << level);
    const double x = std::clamp((u + 0.5) * s - 0.5, 0.0, image.cols - 1.001);
    const double y = std::clamp((v + 0.5) * s - 0.5, 0.0, image.rows - 1.001);
    return SampleBilinear(image, x, y);
  }

  std::vector<cv::Mat> levels_;
};

// The camera poses to colour from: ground truth, else GNSS, with orientation.
const PositionTrack& ColourTrack(const Drive& drive) {
  if (const PositionTrack* track = anchor_internal::OrientedTrack(drive)) return *track;
  Throw(
      "{}: colouring the map needs camera orientations (qw,qx,qy,qz) in the ground truth or "
      "GNSS; the drive has none",
      drive.dir);
}

}  // namespace

void ColorizeCloud(const Drive& drive,
                   const EnuFrame& map_frame,
                   const MapColourOptions& options,
                   int num_threads,
                   PointCloud* cloud,
                   const ProgressCallback& progress,
                   BuildMapSummary* summary) {
  options.Check();
  EPILOC_CHECK(cloud != nullptr, "ColorizeCloud: no cloud");
  const PositionTrack& track = ColourTrack(drive);
  const Undistorter undistorter(drive.camera);
  const Camera& camera = undistorter.undistorted_camera();
  const FrameReader reader(drive);
  const size_t n = cloud->size();
  ColourAccumulator acc;
  acc.sum.assign(n, {0.f, 0.f, 0.f});
  acc.count.assign(n, 0);
  if (options.mode == ColourMode::kClosest) {
    acc.best_distance_m.assign(n, std::numeric_limits<float>::infinity());
  }
  CloudRenderOptions render_options = options.render;
  render_options.num_threads = num_threads;
  // Depth is all the test needs; intensity shading would only cost time.
  PointCloud geometry;
  geometry.positions = cloud->positions;

  std::vector<size_t> frames;
  for (size_t i = 0; i < drive.frames.size(); i += options.frame_step) frames.push_back(i);
  int64_t used_frames = 0;
  const float rel = static_cast<float>(1.0 + options.occlusion_rel);
  const float abs_m = static_cast<float>(options.occlusion_abs_m);
  const double border = options.border_px;
  const double footprint = options.footprint_m;
  for (size_t f = 0; f < frames.size(); ++f) {
    const FrameRecord& record = drive.frames[frames[f]];
    const auto sample = track.Interpolate(record.timestamp_s, drive.max_gap_s);
    if (progress) progress(static_cast<int64_t>(f + 1), static_cast<int64_t>(frames.size()));
    if (!sample || !sample->enu_from_cam) continue;
    const Rigid3d map_from_cam = MapFromSample(map_frame, sample->position, *sample->enu_from_cam);
    const Rigid3d cam_from_map = map_from_cam.Inverse();
    const MipImage image(undistorter.Undistort(reader.ReadColour(frames[f])), 5);
    const CloudRenderResult render = RenderCloud(geometry, camera, cam_from_map, render_options);
    ++used_frames;

    const Eigen::Matrix3f r = cam_from_map.rotation.toRotationMatrix().cast<float>();
    const Eigen::Vector3f centre = map_from_cam.translation.cast<float>();
    const float max_range = static_cast<float>(options.max_range_m);
    const float min_range = static_cast<float>(options.min_range_m);
    const int chunks = std::max(1, num_threads);
    ParallelFor(chunks, num_threads, [&](int64_t chunk64) {
      const int chunk = static_cast<int>(chunk64);
      const size_t begin = n * chunk / chunks;
      const size_t end = n * (chunk + 1) / chunks;
      for (size_t i = begin; i < end; ++i) {
        const Eigen::Vector3f d = cloud->positions[i] - centre;
        const float distance = d.norm();
        if (distance > max_range || distance < min_range) continue;
        const Eigen::Vector3f x = r * d;
        if (x.z() < render_options.near_m) continue;
        const double u = camera.fx * x.x() / x.z() + camera.cx;
        const double v = camera.fy * x.y() / x.z() + camera.cy;
        if (u < border || v < border || u > camera.width - 1 - border ||
            v > camera.height - 1 - border) {
          continue;
        }
        const float depth = render.depth.at<float>(static_cast<int>(std::lround(v)),
                                                   static_cast<int>(std::lround(u)));
        if (depth <= 0.f || x.z() > depth * rel + abs_m) continue;  // occluded
        const std::array<float, 3> rgb = image.Sample(u, v, footprint * camera.fx / x.z());
        if (options.mode == ColourMode::kClosest) {
          if (distance >= acc.best_distance_m[i]) continue;
          acc.best_distance_m[i] = distance;
          acc.sum[i] = rgb;
          acc.count[i] = 1;
        } else {
          for (int c = 0; c < 3; ++c) acc.sum[i][c] += rgb[c];
          ++acc.count[i];
        }
      }
    });
  }
  if (used_frames == 0) {
    Throw("{}: no frame of the drive has a camera pose to colour the map from", drive.dir);
  }

  PointCloud out;
  out.Reserve(n, cloud->HasIntensity(), true);
  int64_t coloured = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool seen = acc.count[i] > 0;
    coloured += seen ? 1 : 0;
    if (!seen && !options.keep_uncoloured) continue;
    out.positions.push_back(cloud->positions[i]);
    if (cloud->HasIntensity()) out.intensity.push_back(cloud->intensity[i]);
    std::array<uint8_t, 3> rgb = {128, 128, 128};
    if (seen) {
      for (int c = 0; c < 3; ++c) {
        rgb[c] = static_cast<uint8_t>(
            std::clamp(std::lround(acc.sum[i][c] / acc.count[i]), 0L, 255L));
      }
    }
    out.rgb.push_back(rgb);
  }
  const int64_t dropped = static_cast<int64_t>(n - out.size());
  spdlog::info("colour: {} of {} points seen by {} frames ({}){}", coloured, n, used_frames,
               ColourModeName(options.mode),
               dropped > 0 ? fmt::format(", {} unseen points dropped", dropped) : "");
  if (summary) {
    summary->num_colour_frames = used_frames;
    summary->num_coloured_points = coloured;
    summary->num_dropped_uncoloured = dropped;
  }
  *cloud = std::move(out);
}

}  // namespace epiloc
