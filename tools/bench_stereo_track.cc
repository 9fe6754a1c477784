// Whether a drive's ground-truth track is metric, measured with a calibrated, rectified stereo
// pair: two drives of the same frames (e.g. `epiloc import-kitti --camera 0` and `--camera 1`),
// the second camera to the right of the first. Prints figures; not a test.
//
// The stereo pair's baseline is taken from the two drives' ground truth at the same frame (the
// calibration's lever arm between the cameras, applied to one pose of the unit: no track error
// enters it). Every `--step` frames:
// (1) SIFT features of the left image at frame k matched to the right image (same row within
//     --max-row-px, ratio test), triangulated: Z = fx * baseline / disparity, metric;
// (2) the left features matched to the left image at frame k + step, the camera at k + step
//     placed by PnP (RANSAC, then refined on the inliers) on the stereo points: the camera's
//     motion over the step, metric, from the stereo calibration alone;
// (3) compared with the ground truth's motion of the left camera over the same frames.
// A ratio above 1 means the ground truth's track is shorter than the cameras moved (session 31:
// the shared KITTI drive's OXTS track, 1.048).
//
// Usage: epiloc_bench_stereo_track --left DIR --right DIR [--step 10] [--max-depth 40]
//        [--features 4000] [--max-row-px 1] [--min-inliers 12]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "epiloc/core/error.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"

namespace epiloc {
namespace {

struct Options {
  std::string left_dir, right_dir;
  int step = 10;
  double max_depth_m = 40.0;
  int features = 4000;
  double max_row_px = 1.0;
  int min_inliers = 12;
};

struct Features {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
};

Features Detect(const Drive& drive, const FrameRecord& frame, cv::SIFT& sift) {
  const std::string path = drive.ImagePath(frame);
  const cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (image.empty()) Throw("{}: cannot read the image", path);
  Features f;
  sift.detectAndCompute(image, cv::noArray(), f.keypoints, f.descriptors);
  return f;
}

// Lowe's ratio test (0.75) on the two nearest neighbours: (query, train) index pairs.
std::vector<std::pair<int, int>> Match(const Features& a, const Features& b) {
  std::vector<std::pair<int, int>> out;
  if (a.descriptors.empty() || b.descriptors.rows < 2) return out;
  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(a.descriptors, b.descriptors, knn, 2);
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < 0.75f * m[1].distance) {
      out.emplace_back(m[0].queryIdx, m[0].trainIdx);
    }
  }
  return out;
}

double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

int Run(const Options& o) {
  const Drive left = LoadDrive(o.left_dir);
  const Drive right = LoadDrive(o.right_dir);
  if (!left.ground_truth || !right.ground_truth) Throw("both drives need a ground truth");
  if (left.camera.HasDistortion() || right.camera.HasDistortion()) {
    Throw("the stereo pair must be rectified (no distortion)");
  }
  const Camera& cam = left.camera;
  if (std::abs(cam.fx - right.camera.fx) > 1e-6 * cam.fx ||
      std::abs(cam.cy - right.camera.cy) > 1e-3) {
    Throw("the two cameras are not a rectified pair (fx {} / {}, cy {} / {})", cam.fx,
          right.camera.fx, cam.cy, right.camera.cy);
  }
  std::map<frame_t, const FrameRecord*> right_frames;
  for (const FrameRecord& f : right.frames) right_frames[f.frame] = &f;
  const EnuFrame enu(left.ground_truth->samples.front().position);
  const auto truth = [&](const Drive& d, const FrameRecord& f) -> std::optional<PositionSample> {
    return d.ground_truth->Interpolate(f.timestamp_s, d.max_gap_s);
  };

  // The baseline in the left camera's frame, from the truth (the calibration's lever arm).
  std::vector<double> bx, by, bz;
  for (const FrameRecord& f : left.frames) {
    const auto it = right_frames.find(f.frame);
    if (it == right_frames.end()) continue;
    const auto l = truth(left, f), r = truth(right, *it->second);
    if (!l || !r || !l->enu_from_cam) continue;
    const Eigen::Vector3d b =
        l->enu_from_cam->conjugate() * (enu.ToEnu(r->position) - enu.ToEnu(l->position));
    bx.push_back(b.x());
    by.push_back(b.y());
    bz.push_back(b.z());
  }
  if (bx.empty()) Throw("no frame of both drives has a ground-truth pose");
  const double baseline = Median(bx);
  std::printf("baseline from the truth: %+.4f %+.4f %+.4f m (left camera axes; %zu frames)\n",
              baseline, Median(by), Median(bz), bx.size());
  if (baseline <= 0.0) Throw("the right drive's camera is not to the right of the left one");

  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(o.features);
  const cv::Matx33d k(cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1);
  std::vector<double> ratios;
  double sum_stereo = 0.0, sum_truth = 0.0;
  std::printf("%7s %7s %10s %10s %8s %8s\n", "frame", "to", "stereo m", "truth m", "ratio",
              "inliers");
  // The left features of a step's end are the next step's start: detected once.
  std::optional<std::pair<size_t, Features>> last_left;
  const auto left_features = [&](size_t index) {
    if (!last_left || last_left->first != index) {
      last_left.emplace(index, Detect(left, left.frames[index], *sift));
    }
    return last_left->second;
  };
  for (size_t i = 0; i + o.step < left.frames.size(); i += o.step) {
    const FrameRecord& a = left.frames[i];
    const FrameRecord& b = left.frames[i + o.step];
    const auto ra = right_frames.find(a.frame);
    const auto ta = truth(left, a), tb = truth(left, b);
    if (ra == right_frames.end() || !ta || !tb) continue;
    const double truth_moved = (enu.ToEnu(tb->position) - enu.ToEnu(ta->position)).norm();
    if (truth_moved < 0.5) continue;  // standing: no ratio to speak of
    const Features fa = left_features(i);
    const Features fr = Detect(right, *ra->second, *sift);
    const Features fb = left_features(i + o.step);
    std::map<int, cv::Point3d> stereo;
    for (const auto& [qi, ti] : Match(fa, fr)) {
      const cv::Point2f pl = fa.keypoints[qi].pt, pr = fr.keypoints[ti].pt;
      const double disparity = pl.x - pr.x;
      if (std::abs(pl.y - pr.y) > o.max_row_px || disparity <= 0.0) continue;
      const double z = cam.fx * baseline / disparity;
      if (z > o.max_depth_m) continue;
      stereo[qi] = cv::Point3d((pl.x - cam.cx) * z / cam.fx, (pl.y - cam.cy) * z / cam.fy, z);
    }
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const auto& [qi, ti] : Match(fa, fb)) {
      const auto it = stereo.find(qi);
      if (it == stereo.end()) continue;
      object.push_back(it->second);
      image.emplace_back(fb.keypoints[ti].pt.x, fb.keypoints[ti].pt.y);
    }
    if (static_cast<int>(object.size()) < o.min_inliers) continue;
    cv::Mat rvec, tvec;
    std::vector<int> inliers;
    if (!cv::solvePnPRansac(object, image, k, cv::noArray(), rvec, tvec, false, 2000, 1.0, 0.999,
                            inliers) ||
        static_cast<int>(inliers.size()) < o.min_inliers) {
      continue;
    }
    std::vector<cv::Point3d> in_object;
    std::vector<cv::Point2d> in_image;
    for (const int j : inliers) {
      in_object.push_back(object[j]);
      in_image.push_back(image[j]);
    }
    cv::solvePnP(in_object, in_image, k, cv::noArray(), rvec, tvec, true);
    cv::Matx33d r;
    cv::Rodrigues(rvec, r);
    const cv::Vec3d centre = -(r.t() * cv::Vec3d(tvec));
    const double moved = cv::norm(centre);
    ratios.push_back(moved / truth_moved);
    sum_stereo += moved;
    sum_truth += truth_moved;
    std::printf("%7lld %7lld %10.3f %10.3f %8.4f %8zu\n", static_cast<long long>(a.frame),
                static_cast<long long>(b.frame), moved, truth_moved, moved / truth_moved,
                inliers.size());
  }
  if (ratios.empty()) Throw("no step could be measured");
  std::printf("stereo / truth: median %.4f over %zu steps; summed %.2f / %.2f m = %.4f\n",
              Median(ratios), ratios.size(), sum_stereo, sum_truth, sum_stereo / sum_truth);
  return 0;
}

}  // namespace
}  // namespace epiloc

int main(int argc, char** argv) {
  epiloc::Options o;
  CLI::App app{"Whether a drive's ground-truth track is metric, by a calibrated stereo pair"};
  app.add_option("--left", o.left_dir, "Drive of the left camera")->required();
  app.add_option("--right", o.right_dir, "Drive of the right camera, same frames")->required();
  app.add_option("--step", o.step, "Frames between the two poses compared")->capture_default_str();
  app.add_option("--max-depth", o.max_depth_m, "Stereo points farther are not used, metres")
      ->capture_default_str();
  app.add_option("--features", o.features, "SIFT features per image")->capture_default_str();
  app.add_option("--max-row-px", o.max_row_px, "Stereo matches' row difference at most, pixels")
      ->capture_default_str();
  app.add_option("--min-inliers", o.min_inliers, "Fewer PnP inliers: the step is skipped")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    if (o.step < 1) epiloc::Throw("--step must be >= 1");
    return epiloc::Run(o);
  } catch (const epiloc::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
