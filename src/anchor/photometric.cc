#include "epiloc/anchor/photometric.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Cholesky>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using Vector8d = Eigen::Matrix<double, 8, 1>;
using Matrix8d = Eigen::Matrix<double, 8, 8>;

// One level of the frame: intensity and its gradients (float, grey levels per pixel).
struct FrameLevel {
  cv::Mat image, gx, gy;
  Camera camera;
};

// A rendered pixel used in the alignment: its point in the rendering camera and its grey value.
struct Sample {
  Eigen::Vector3d x;
  double grey;
};

float Bilinear(const cv::Mat& image, double u, double v) {
  const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
  const float a = static_cast<float>(u - u0), b = static_cast<float>(v - v0);
  const float* r0 = image.ptr<float>(v0) + u0;
  const float* r1 = image.ptr<float>(v0 + 1) + u0;
  return (1 - b) * ((1 - a) * r0[0] + a * r0[1]) + b * ((1 - a) * r1[0] + a * r1[1]);
}

std::vector<FrameLevel> FramePyramid(const cv::Mat& frame, const Camera& camera, int levels) {
  std::vector<FrameLevel> pyramid;
  cv::Mat image;
  frame.convertTo(image, CV_32F);
  for (int l = 0; l <= levels; ++l) {
    if (l > 0) cv::pyrDown(pyramid.back().image, image);
    FrameLevel level;
    level.image = image;
    cv::Sobel(image, level.gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
    cv::Sobel(image, level.gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
    const double f = 1.0 / (1 << l);
    level.camera = camera.Scaled(f);
    level.camera.width = image.cols;
    level.camera.height = image.rows;
    pyramid.push_back(level);
  }
  return pyramid;
}

// Pixels of a rendering with depth, off depth edges and with a strong gradient, lifted.
std::vector<Sample> SelectSamples(const CloudRenderResult& render,
                                  const Camera& camera,
                                  const PhotometricOptions& options) {
  cv::Mat grey;
  if (render.image.channels() == 3) {
    cv::cvtColor(render.image, grey, cv::COLOR_BGR2GRAY);
  } else {
    grey = render.image;
  }
  cv::Mat g;
  grey.convertTo(g, CV_32F);
  cv::Mat gx, gy;
  cv::Sobel(g, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(g, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  struct Candidate {
    float strength;
    int u, v;
  };
  std::vector<Candidate> candidates;
  const float min2 = static_cast<float>(options.min_gradient * options.min_gradient);
  // Two pixels of margin: the 3x3 depth test and Sobel must not see the empty background.
  for (int v = 2; v < g.rows - 2; ++v) {
    for (int u = 2; u < g.cols - 2; ++u) {
      const float s = gx.at<float>(v, u) * gx.at<float>(v, u) + gy.at<float>(v, u) * gy.at<float>(v, u);
      if (s < min2) continue;
      float lo = INFINITY, hi = 0.f;
      for (int dv = -2; dv <= 2; ++dv) {
        for (int du = -2; du <= 2; ++du) {
          const float d = render.depth.at<float>(v + dv, u + du);
          lo = std::min(lo, d);
          hi = std::max(hi, d);
        }
      }
      if (lo <= 0.f || hi - lo > options.max_depth_step * lo) continue;
      candidates.push_back({s, u, v});
    }
  }
  if (static_cast<int>(candidates.size()) > options.max_pixels) {
    std::nth_element(candidates.begin(), candidates.begin() + options.max_pixels, candidates.end(),
                     [](const Candidate& a, const Candidate& b) { return a.strength > b.strength; });
    candidates.resize(options.max_pixels);
  }
  std::vector<Sample> samples;
  samples.reserve(candidates.size());
  for (const Candidate& c : candidates) {
    const double z = render.depth.at<float>(c.v, c.u);
    samples.push_back({Eigen::Vector3d((c.u - camera.cx) / camera.fx * z,
                                       (c.v - camera.cy) / camera.fy * z, z),
                       static_cast<double>(g.at<float>(c.v, c.u))});
  }
  return samples;
}

// Normal equations of the residuals at relative pose dT and brightness (a, b); returns the
// robust cost and fills the NCC of the pixels inside the frame.
double Accumulate(const std::vector<Sample>& samples,
                  const FrameLevel& level,
                  const Rigid3d& delta,
                  double a,
                  double b,
                  double huber,
                  Matrix8d* h,
                  Vector8d* g,
                  int* used,
                  double* ncc) {
  h->setZero();
  g->setZero();
  *used = 0;
  double cost = 0;
  double si = 0, sr = 0, sii = 0, srr = 0, sir = 0;
  const Camera& c = level.camera;
  const Eigen::Matrix3d r = delta.rotation.toRotationMatrix();
  for (const Sample& s : samples) {
    const Eigen::Vector3d x = r * s.x + delta.translation;
    if (x.z() < 0.1) continue;
    const double u = c.fx * x.x() / x.z() + c.cx;
    const double v = c.fy * x.y() / x.z() + c.cy;
    if (!(u >= 1 && v >= 1 && u < c.width - 2 && v < c.height - 2)) continue;
    const double intensity = Bilinear(level.image, u, v);
    const double res = intensity - (a * s.grey + b);
    const double abs_res = std::abs(res);
    const double w = abs_res <= huber ? 1.0 : huber / abs_res;
    cost += abs_res <= huber ? 0.5 * res * res : huber * (abs_res - 0.5 * huber);
    const double ix = Bilinear(level.gx, u, v), iy = Bilinear(level.gy, u, v);
    const double iz = 1.0 / x.z();
    // dI/dx for the point in the frame camera, then x' = x + w x x + t for the update.
    const Eigen::Vector3d di(ix * c.fx * iz, iy * c.fy * iz,
                             -(ix * c.fx * x.x() + iy * c.fy * x.y()) * iz * iz);
    Vector8d j;
    j.head<3>() = x.cross(di);  // d/d omega of di . (omega x x) = (x x di) . omega
    j.segment<3>(3) = di;
    j(6) = -s.grey;
    j(7) = -1.0;
    h->selfadjointView<Eigen::Upper>().rankUpdate(j, w);
    *g += w * res * j;
    ++*used;
    si += intensity;
    sr += s.grey;
    sii += intensity * intensity;
    srr += s.grey * s.grey;
    sir += intensity * s.grey;
  }
  *h = h->selfadjointView<Eigen::Upper>();
  if (*used > 1) {
    const double n = *used;
    const double cov = sir / n - (si / n) * (sr / n);
    const double vi = sii / n - (si / n) * (si / n), vr = srr / n - (sr / n) * (sr / n);
    *ncc = vi > 0 && vr > 0 ? cov / std::sqrt(vi * vr) : 0.0;
  } else {
    *ncc = 0.0;
  }
  return cost;
}

Rigid3d ExpUpdate(const Eigen::Matrix<double, 6, 1>& step) {
  const Eigen::Vector3d w = step.head<3>();
  const double angle = w.norm();
  const Eigen::Quaterniond q =
      angle > 1e-12 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / angle))
                    : Eigen::Quaterniond::Identity();
  return Rigid3d(q, step.tail<3>());
}

}  // namespace

void PhotometricOptions::Check() const {
  EPILOC_CHECK(finest_level >= 0 && coarsest_level >= finest_level && coarsest_level <= 6,
               "photometric options: need 0 <= finest_level <= coarsest_level <= 6");
  EPILOC_CHECK(rounds >= 1, "photometric options: rounds must be >= 1");
  EPILOC_CHECK(max_iterations >= 1, "photometric options: max_iterations must be >= 1");
  EPILOC_CHECK(max_pixels >= 100, "photometric options: max_pixels must be >= 100");
  EPILOC_CHECK(std::isfinite(min_gradient) && min_gradient >= 0,
               "photometric options: min_gradient must be >= 0");
  EPILOC_CHECK(std::isfinite(huber_grey) && huber_grey > 0,
               "photometric options: huber_grey must be > 0");
  EPILOC_CHECK(std::isfinite(max_depth_step) && max_depth_step > 0,
               "photometric options: max_depth_step must be > 0");
  EPILOC_CHECK(min_ncc >= -1 && min_ncc <= 1, "photometric options: min_ncc must be in [-1, 1]");
}

PhotometricResult RefinePhotometric(const cv::Mat& frame,
                                    const Camera& camera,
                                    const PointCloud& map,
                                    const Rigid3d& cam_from_world,
                                    const CloudRenderOptions& render_options,
                                    const PhotometricOptions& options) {
  options.Check();
  EPILOC_CHECK(frame.type() == CV_8UC1 && frame.cols == camera.width && frame.rows == camera.height,
               "RefinePhotometric: expected an 8-bit grey frame of the camera's size");
  PhotometricResult result;
  result.cam_from_world = cam_from_world;
  const std::vector<FrameLevel> pyramid = FramePyramid(frame, camera, options.coarsest_level);
  for (int round = 0; round < options.rounds; ++round) {
    for (int l = options.coarsest_level; l >= options.finest_level; --l) {
      const FrameLevel& level = pyramid[l];
      const CloudRenderResult render =
          RenderCloud(map, level.camera, result.cam_from_world, render_options);
      const std::vector<Sample> samples = SelectSamples(render, level.camera, options);
      if (samples.size() < 100) {
        result.message = fmt::format("{} textured rendered pixels at level {} (< 100)",
                                     samples.size(), l);
        return result;
      }
      // Brightness from the moments of the two images at the start.
      Matrix8d h;
      Vector8d g;
      int used = 0;
      double ncc = 0;
      double a = 1.0, b = 0.0;
      {
        double si = 0, sr = 0, sii = 0, srr = 0;
        int n = 0;
        for (const Sample& s : samples) {
          const Eigen::Vector3d& x = s.x;
          const double u = level.camera.fx * x.x() / x.z() + level.camera.cx;
          const double v = level.camera.fy * x.y() / x.z() + level.camera.cy;
          if (!(u >= 1 && v >= 1 && u < level.camera.width - 2 && v < level.camera.height - 2)) {
            continue;
          }
          const double i = Bilinear(level.image, u, v);
          si += i;
          sii += i * i;
          sr += s.grey;
          srr += s.grey * s.grey;
          ++n;
        }
        if (n > 1) {
          const double vi = sii / n - (si / n) * (si / n), vr = srr / n - (sr / n) * (sr / n);
          a = vr > 1e-6 && vi > 0 ? std::sqrt(vi / vr) : 1.0;
          b = si / n - a * sr / n;
        }
      }
      Rigid3d delta;
      double lambda = 1e-4;
      double cost = Accumulate(samples, level, delta, a, b, options.huber_grey, &h, &g, &used, &ncc);
      for (int it = 0; it < options.max_iterations; ++it) {
        ++result.iterations;
        Matrix8d damped = h;
        damped.diagonal() *= 1.0 + lambda;
        const Vector8d step = damped.ldlt().solve(-g);
        if (!step.allFinite()) break;
        const Rigid3d candidate = ExpUpdate(step.head<6>()) * delta;
        Matrix8d h2;
        Vector8d g2;
        int used2 = 0;
        double ncc2 = 0;
        const double cost2 = Accumulate(samples, level, candidate, a + step(6), b + step(7),
                                        options.huber_grey, &h2, &g2, &used2, &ncc2);
        if (used2 < used / 2 || cost2 / std::max(used2, 1) > cost / std::max(used, 1)) {
          lambda *= 10;  // rejected: a smaller, more gradient-like step
          if (lambda > 1e4) break;
          continue;
        }
        lambda = std::max(lambda / 10, 1e-6);
        delta = candidate;
        a += step(6);
        b += step(7);
        h = h2;
        g = g2;
        cost = cost2;
        used = used2;
        ncc = ncc2;
        const double scale = samples.empty() ? 1.0 : samples[samples.size() / 2].x.z();
        if (step.head<3>().norm() < options.converged_step &&
            step.segment<3>(3).norm() < options.converged_step * scale) {
          break;
        }
      }
      result.cam_from_world = delta * result.cam_from_world;
      result.ncc = ncc;
      result.num_pixels = used;
    }
  }
  if (result.ncc < options.min_ncc) {
    result.message = fmt::format("correlation of frame and rendering {:.2f} below {:.2f}",
                                 result.ncc, options.min_ncc);
    return result;
  }
  result.success = true;
  return result;
}

}  // namespace epiloc
