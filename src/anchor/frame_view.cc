#include "epiloc/anchor/frame_view.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "anchor_internal.h"
#include "epiloc/anchor/map_photos.h"
#include "epiloc/camera/undistorter.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
#include "epiloc/io/frame_reader.h"

namespace epiloc {

ViewPose ParseViewPose(const std::string& name) {
  if (name == "auto") return ViewPose::kAuto;
  if (name == "truth") return ViewPose::kTruth;
  if (name == "gnss") return ViewPose::kGnss;
  Throw("unknown pose source '{}' (known: auto, truth, gnss)", name);
}

void FrameViewInputs::Check() const {
  EPILOC_CHECK(!cloud_path.empty(), "--cloud is required");
  EPILOC_CHECK(!drive_dir.empty(), "--drive is required");
  EPILOC_CHECK(frame >= 0, "--frame must be >= 0, got {}", frame);
  CheckGeodetic(map_origin, "map origin");
  prior.Check();
  render.Check();
  EPILOC_CHECK(std::isfinite(load_radius_m) && load_radius_m > 0,
               "render: load_radius_m must be > 0");
}

FrameView RenderFrameView(const FrameViewInputs& inputs) {
  inputs.Check();
  const Drive drive = LoadDrive(inputs.drive_dir);
  size_t index = drive.frames.size();
  for (size_t i = 0; i < drive.frames.size(); ++i) {
    if (drive.frames[i].frame == inputs.frame) index = i;
  }
  if (index == drive.frames.size()) {
    Throw("{}: frame {} is not in the drive", inputs.drive_dir, inputs.frame);
  }
  const FrameRecord& record = drive.frames[index];
  const std::unique_ptr<TiledCloud> map =
      anchor_internal::OpenMap(inputs.cloud_path, "", 20000000);
  const EnuFrame map_frame(inputs.map_origin);
  anchor_internal::CheckMapNearDrive(inputs.cloud_path, *map, map_frame, drive,
                                     inputs.max_map_distance_m);

  FrameView view;
  std::optional<PositionSample> truth;
  if (drive.ground_truth) truth = drive.ground_truth->Interpolate(record.timestamp_s, drive.max_gap_s);
  const bool truth_usable = truth && truth->enu_from_cam;
  ViewPose source = inputs.pose;
  if (source == ViewPose::kAuto) source = truth_usable ? ViewPose::kTruth : ViewPose::kGnss;
  PointCloud local;
  if (inputs.map_from_cam) {
    view.map_from_cam = *inputs.map_from_cam;
    view.pose_source = "given";
    local = map->Load(view.map_from_cam.translation, inputs.load_radius_m);
  } else if (source == ViewPose::kTruth) {
    if (!truth_usable) {
      Throw("{}: no ground-truth camera orientation at frame {} (use --prior gnss or --pose)",
            inputs.drive_dir, inputs.frame);
    }
    view.map_from_cam =
        anchor_internal::MapFromSample(map_frame, truth->position, *truth->enu_from_cam);
    view.pose_source = "ground truth";
    local = map->Load(view.map_from_cam.translation, inputs.load_radius_m);
  } else {
    const auto gnss = drive.gnss.Interpolate(record.timestamp_s, drive.max_gap_s);
    if (!gnss) Throw("{}: no GNSS position at frame {}", inputs.drive_dir, inputs.frame);
    local = map->Load(map_frame.ToEnu(gnss->position), inputs.load_radius_m);
    const auto prior = MakePosePrior(drive.gnss, map_frame, local, record.frame,
                                     record.timestamp_s, drive.max_gap_s, inputs.prior);
    if (!prior) Throw("{}: no GNSS heading at frame {}", inputs.drive_dir, inputs.frame);
    view.map_from_cam = prior->map_from_cam;
    view.pose_source = "GNSS prior";
  }

  const Undistorter undistorter(drive.camera);
  view.camera = undistorter.undistorted_camera();
  const FrameReader reader(drive);
  view.frame = undistorter.Undistort(drive.colour ? reader.ReadColour(index)
                                                  : reader.ReadGrey(index));
  view.render = RenderCloud(local, view.camera, view.map_from_cam.Inverse(), inputs.render);
  if (cv::countNonZero(view.render.depth > 0.f) == 0) {
    Throw("{}: the cloud does not cover frame {} of {}: no point in view at the {} pose",
          inputs.cloud_path, inputs.frame, inputs.drive_dir, view.pose_source);
  }
  if (!inputs.photos_dir.empty()) {
    const MapPhotos photos(inputs.photos_dir, map_frame, inputs.photos);
    MapPhotoCache(photos, local, inputs.render)
        .Texture(view.camera, view.map_from_cam.Inverse(), &view.render);
  }
  return view;
}

void WriteDepthPng(const cv::Mat& depth, const std::string& path) {
  EPILOC_CHECK(depth.type() == CV_32F, "WriteDepthPng: expected a CV_32F depth buffer");
  cv::Mat scaled(depth.size(), CV_16U);
  for (int v = 0; v < depth.rows; ++v) {
    const float* in = depth.ptr<float>(v);
    uint16_t* out = scaled.ptr<uint16_t>(v);
    for (int u = 0; u < depth.cols; ++u) {
      out[u] = static_cast<uint16_t>(std::clamp(std::lround(in[u] * 256.0f), 0L, 65535L));
    }
  }
  AtomicFile file(path);
  if (!cv::imwrite(file.temp_path(), scaled)) Throw("{}: cannot write image", path);
  file.Commit();
}

cv::Mat StackFrameAndRendering(const cv::Mat& frame, const cv::Mat& rendering) {
  const auto bgr = [](const cv::Mat& image) {
    cv::Mat out;
    if (image.channels() == 1) {
      cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
    } else {
      out = image;
    }
    return out;
  };
  cv::Mat stacked;
  cv::vconcat(bgr(frame), bgr(rendering), stacked);
  return stacked;
}

}  // namespace epiloc
