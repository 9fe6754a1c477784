// A north-up map of a synthetic world with trajectories, drawn with OpenCV.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "epiloc/synth/drive_gen.h"

namespace epiloc {

cv::Mat DrawTopView(const World& world, const std::vector<TopViewTrack>& tracks, int max_size_px) {
  // Extent: the road and its buildings, not the ground around them.
  Eigen::Vector2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (const Surface& s : world.surfaces) {
    if (s.kind == SurfaceKind::kGround || s.texture < 0) continue;
    for (const Eigen::Vector3d& c : s.corners_in_world) {
      lo = lo.cwiseMin(c.head<2>());
      hi = hi.cwiseMax(c.head<2>());
    }
  }
  lo -= Eigen::Vector2d(10, 10);
  hi += Eigen::Vector2d(10, 10);
  const double scale = max_size_px / std::max(hi.x() - lo.x(), hi.y() - lo.y());  // px per metre
  cv::Mat image(static_cast<int>((hi.y() - lo.y()) * scale),
                static_cast<int>((hi.x() - lo.x()) * scale), CV_8UC3, cv::Scalar(150, 190, 160));
  constexpr int kShift = 4;  // sub-pixel drawing
  const auto px = [&](const Eigen::Vector3d& p) {
    return cv::Point(static_cast<int>(std::lround((p.x() - lo.x()) * scale * (1 << kShift))),
                     static_cast<int>(std::lround((hi.y() - p.y()) * scale * (1 << kShift))));
  };
  const auto fill = [&](const Surface& s, const cv::Scalar& colour) {
    std::vector<cv::Point> poly;
    for (const Eigen::Vector3d& c : s.corners_in_world) poly.push_back(px(c));
    cv::fillConvexPoly(image, poly, colour, cv::LINE_AA, kShift);
  };
  const int line = std::max(1, static_cast<int>(std::lround(scale * 0.4)));
  for (const SurfaceKind kind :
       {SurfaceKind::kSidewalk, SurfaceKind::kRoad, SurfaceKind::kBackground, SurfaceKind::kWall,
        SurfaceKind::kFacade, SurfaceKind::kCar, SurfaceKind::kHedge, SurfaceKind::kTreeCrown,
        SurfaceKind::kPole, SurfaceKind::kSign}) {
    for (const Surface& s : world.surfaces) {
      if (s.kind != kind || s.texture < 0) continue;
      const std::array<Eigen::Vector3d, 4>& c = s.corners_in_world;
      switch (kind) {
        case SurfaceKind::kSidewalk:
          fill(s, cv::Scalar(200, 200, 200));
          break;
        case SurfaceKind::kRoad:
          fill(s, cv::Scalar(90, 90, 90));
          break;
        case SurfaceKind::kCar:
          if (std::abs(s.Normal().z()) > 0.5) fill(s, cv::Scalar(180, 120, 60));
          break;
        case SurfaceKind::kHedge:
        case SurfaceKind::kTreeCrown:
          if (std::abs(s.Normal().z()) > 0.5) fill(s, cv::Scalar(40, 120, 50));
          break;
        case SurfaceKind::kFacade:
        case SurfaceKind::kWall:
        case SurfaceKind::kBackground:
          cv::line(image, px(c[2]), px(c[3]),
                   kind == SurfaceKind::kBackground ? cv::Scalar(120, 140, 170)
                                                    : cv::Scalar(40, 60, 120),
                   kind == SurfaceKind::kFacade ? 2 * line : line, cv::LINE_AA, kShift);
          break;
        default:
          cv::circle(image, px(0.25 * (c[0] + c[1] + c[2] + c[3])), (line + 1) << kShift,
                     cv::Scalar(20, 20, 20), cv::FILLED, cv::LINE_AA, kShift);
      }
    }
  }
  for (const TopViewTrack& track : tracks) {
    std::vector<cv::Point> pts;
    for (const Eigen::Vector3d& p : track.points_in_world) pts.push_back(px(p));
    if (track.dots) {
      for (const cv::Point& p : pts) {
        cv::circle(image, p, (2 * line + 1) << kShift, track.bgr, cv::FILLED, cv::LINE_AA, kShift);
      }
    } else if (pts.size() > 1) {
      cv::circle(image, pts.front(), (3 * line + 2) << kShift, track.bgr, cv::FILLED, cv::LINE_AA,
                 kShift);  // start
      cv::polylines(image, pts, false, track.bgr, std::max(2, line), cv::LINE_AA, kShift);
    }
  }
  // Legend, scale bar (50 m) and north arrow.
  int y = 24;
  for (const TopViewTrack& track : tracks) {
    if (track.label.empty()) continue;
    cv::line(image, cv::Point(20, y - 5), cv::Point(50, y - 5), track.bgr, 3, cv::LINE_AA);
    cv::putText(image, track.label, cv::Point(58, y), cv::FONT_HERSHEY_SIMPLEX, 0.55,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    y += 22;
  }
  const int bar = static_cast<int>(std::lround(50 * scale));
  const cv::Point b0(20, image.rows - 20);
  cv::line(image, b0, b0 + cv::Point(bar, 0), cv::Scalar(0, 0, 0), 3);
  cv::putText(image, "50 m", b0 + cv::Point(0, -8), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  const cv::Point n0(image.cols - 30, 70);
  cv::arrowedLine(image, n0, n0 + cv::Point(0, -45), cv::Scalar(0, 0, 0), 2, cv::LINE_AA, 0, 0.3);
  cv::putText(image, "N", n0 + cv::Point(-8, 22), cv::FONT_HERSHEY_SIMPLEX, 0.7,
              cv::Scalar(0, 0, 0), 2, cv::LINE_AA);
  return image;
}

}  // namespace epiloc
