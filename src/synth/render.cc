#include "epiloc/synth/render.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

constexpr int kSkyTableSize = 4096;
double Sq(double x) { return x * x; }
// sin(elevation) of sky table entry i.
double SkyUp(int i) { return 2.0 * i / kSkyTableSize - 1.0; }

// log2 to about 0.01, enough to choose mip levels (std::log2 costs more than the lookup).
float FastLog2(float x) {
  uint32_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  const float exponent = static_cast<float>(static_cast<int>((bits >> 23) & 255) - 128);
  bits = (bits & 0x007FFFFFu) | 0x3F800000u;  // mantissa in [1, 2)
  float m;
  std::memcpy(&m, &bits, sizeof m);
  return exponent + (-0.33582878f * m + 2.0f) * m - 0.65871759f;
}

// A function a * x + b * y + c of the pixel coordinates.
struct Linear {
  double a = 0, b = 0, c = 0;
  double operator()(double x, double y) const { return a * x + b * y + c; }
};

Linear operator*(double k, const Linear& f) { return {k * f.a, k * f.b, k * f.c}; }
Linear operator+(const Linear& f, const Linear& g) { return {f.a + g.a, f.b + g.b, f.c + g.c}; }

// Turns v . (x', y', 1) over normalised coordinates into a function of the pixel coordinates.
Linear FromNormalized(const Eigen::Vector3d& v, const Camera& cam) {
  return {v.x() / cam.fx, v.y() / cam.fy,
          v.z() - v.x() * cam.cx / cam.fx - v.y() * cam.cy / cam.fy};
}

// Per-frame set-up of one quad: everything in pixel coordinates of the render camera.
struct QuadSetup {
  int surface = -1;
  const Texture* texture = nullptr;
  Linear w;                           // inverse depth 1/z (1/m)
  Linear tu, tv;                      // level-0 texel coordinates times w
  double det = 0;                     // |det [tu; tv; w]|: texel area per pixel area is det / w^3
  std::array<Linear, 6> constraints;  // inside where all >= 0
  int x0 = 0, x1 = -1, y0 = 0, y1 = -1;
  double nearest_z = 0;
};

cv::Vec3f Bilinear(const cv::Mat& image, double x, double y) {
  x = std::min(std::max(x, 0.0), image.cols - 1.0);
  y = std::min(std::max(y, 0.0), image.rows - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const cv::Vec3b* r0 = image.ptr<cv::Vec3b>(y0);
  const cv::Vec3b* r1 = image.ptr<cv::Vec3b>(y1);
  cv::Vec3f out;
  for (int c = 0; c < 3; ++c) {
    const float top = r0[x0][c] + (r0[x1][c] - r0[x0][c]) * fx;
    const float bottom = r1[x0][c] + (r1[x1][c] - r1[x0][c]) * fx;
    out[c] = top + (bottom - top) * fy;
  }
  return out;
}

cv::Vec3f SampleTexture(const Texture& texture, double tu, double tv, double lod) {
  const int num_levels = static_cast<int>(texture.levels.size());
  if (lod <= 0 || num_levels <= 1) return Bilinear(texture.levels[0], tu, tv);
  lod = std::min(lod, num_levels - 1.0);
  const int l0 = static_cast<int>(lod);
  const double f = lod - l0;
  // Level l pixel j lies at level-0 coordinate j * 2^l (cv::pyrDown).
  const double s0 = 1.0 / (1 << l0);
  const cv::Vec3f a = Bilinear(texture.levels[l0], tu * s0, tv * s0);
  if (f < 1e-3 || l0 + 1 >= num_levels) return a;
  const cv::Vec3f b = Bilinear(texture.levels[l0 + 1], tu * s0 * 0.5, tv * s0 * 0.5);
  return a * static_cast<float>(1 - f) + b * static_cast<float>(f);
}

cv::Vec3f BilinearF(const cv::Mat& image, double x, double y) {
  x = std::min(std::max(x, 0.0), image.cols - 1.0);
  y = std::min(std::max(y, 0.0), image.rows - 1.0);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const cv::Vec3f* r0 = image.ptr<cv::Vec3f>(y0);
  const cv::Vec3f* r1 = image.ptr<cv::Vec3f>(y1);
  return (r0[x0] * (1 - fx) + r0[x1] * fx) * (1 - fy) + (r1[x0] * (1 - fx) + r1[x1] * fx) * fy;
}

// Clips the camera-frame polygon to z >= near (Sutherland-Hodgman).
std::vector<Eigen::Vector3d> ClipNear(const std::array<Eigen::Vector3d, 4>& poly, double near) {
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d& a = poly[i];
    const Eigen::Vector3d& b = poly[(i + 1) % 4];
    const bool ina = a.z() >= near, inb = b.z() >= near;
    if (ina) out.push_back(a);
    if (ina != inb) out.push_back(a + (b - a) * ((near - a.z()) / (b.z() - a.z())));
  }
  return out;
}

bool SetUpQuad(const Surface& s,
               const Texture& texture,
               int index,
               const Camera& cam,
               const Eigen::Matrix3d& r,
               const Eigen::Vector3d& t,
               double near,
               QuadSetup* q) {
  std::array<Eigen::Vector3d, 4> corners;
  for (int i = 0; i < 4; ++i) corners[i] = r * s.corners_in_world[i] + t;
  const std::vector<Eigen::Vector3d> clipped = ClipNear(corners, near);
  if (clipped.size() < 3) return false;
  double min_x = 1e300, max_x = -1e300, min_y = 1e300, max_y = -1e300;
  q->nearest_z = 1e300;
  for (const Eigen::Vector3d& p : clipped) {
    const double x = cam.fx * p.x() / p.z() + cam.cx, y = cam.fy * p.y() / p.z() + cam.cy;
    min_x = std::min(min_x, x);
    max_x = std::max(max_x, x);
    min_y = std::min(min_y, y);
    max_y = std::max(max_y, y);
    q->nearest_z = std::min(q->nearest_z, p.z());
  }
  q->x0 = static_cast<int>(std::max(0.0, std::ceil(min_x - 1e-3)));
  q->x1 = static_cast<int>(std::min(cam.width - 1.0, std::floor(max_x + 1e-3)));
  q->y0 = static_cast<int>(std::max(0.0, std::ceil(min_y - 1e-3)));
  q->y1 = static_cast<int>(std::min(cam.height - 1.0, std::floor(max_y + 1e-3)));
  if (q->x0 > q->x1 || q->y0 > q->y1) return false;

  const Eigen::Vector3d n = r * s.Normal();
  const double d = s.PlaneOffset() + n.dot(t);
  if (std::abs(d) < 1e-9) return false;  // the camera lies in the plane
  const double mpp = texture.metres_per_pixel;
  const Eigen::Vector3d w = n / d;
  const Eigen::Vector3d u_c = r * s.u_axis, v_c = r * s.v_axis;
  const Eigen::Vector3d o_c = r * s.texture_origin_in_world + t;
  // u = (u_c . ray) / w - u_c . o_c, texel = u / mpp - 0.5; all times w is linear in the ray.
  const Eigen::Vector3d tu = (u_c - u_c.dot(o_c) * w) / mpp - 0.5 * w;
  const Eigen::Vector3d tv = (v_c - v_c.dot(o_c) * w) / mpp - 0.5 * w;
  q->surface = index;
  q->texture = &texture;
  q->w = FromNormalized(w, cam);
  q->tu = FromNormalized(tu, cam);
  q->tv = FromNormalized(tv, cam);
  Eigen::Matrix3d m;
  m << q->tu.a, q->tu.b, q->tu.c, q->tv.a, q->tv.b, q->tv.c, q->w.a, q->w.b, q->w.c;
  q->det = std::abs(m.determinant());
  // Quad edges in texel coordinates; E(T) = orient * cross(edge, T - T_i) >= 0 inside, times w.
  std::array<Eigen::Vector2d, 4> tc;
  double area = 0;
  for (int i = 0; i < 4; ++i) {
    tc[i] = s.TextureCoordinates(s.corners_in_world[i]) / mpp - Eigen::Vector2d(0.5, 0.5);
  }
  for (int i = 0; i < 4; ++i) {
    area += tc[i].x() * tc[(i + 1) % 4].y() - tc[i].y() * tc[(i + 1) % 4].x();
  }
  const double orient = area >= 0 ? 1.0 : -1.0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d e = tc[(i + 1) % 4] - tc[i];
    q->constraints[i] = (orient * e.x()) * q->tv + (-orient * e.y()) * q->tu +
                        (orient * (e.y() * tc[i].x() - e.x() * tc[i].y())) * q->w;
  }
  q->constraints[4] = q->w;                                      // in front of the camera
  q->constraints[5] = Linear{0, 0, 1.0 / near} + (-1.0) * q->w;  // behind the near plane
  return true;
}

// Rasterises one quad into the colour, inverse-depth and id buffers.
void Rasterise(
    const QuadSetup& q, bool mipmapping, cv::Mat& colour, cv::Mat& inverse_depth, cv::Mat& ids) {
  const Texture& texture = *q.texture;
  constexpr double kTolerancePx = 1e-4;  // shared edges are covered by both quads, never neither
  for (int y = q.y0; y <= q.y1; ++y) {
    double lo = q.x0, hi = q.x1;
    for (const Linear& f : q.constraints) {
      const double rest = f.b * y + f.c;
      if (f.a > 0) {
        lo = std::max(lo, std::ceil(-rest / f.a - kTolerancePx));
      } else if (f.a < 0) {
        hi = std::min(hi, std::floor(-rest / f.a + kTolerancePx));
      } else if (rest < 0) {
        hi = -1;
      }
    }
    if (lo > hi) continue;
    cv::Vec3f* c_row = colour.ptr<cv::Vec3f>(y);
    double* z_row = inverse_depth.ptr<double>(y);
    int* id_row = ids.ptr<int>(y);
    const double w_row = q.w.b * y + q.w.c, u_row = q.tu.b * y + q.tu.c,
                 v_row = q.tv.b * y + q.tv.c;
    for (int x = static_cast<int>(lo); x <= static_cast<int>(hi); ++x) {
      const double w = q.w.a * x + w_row;
      if (w <= z_row[x] || w <= 0) continue;
      const double inv_w = 1.0 / w;
      const double tu = (q.tu.a * x + u_row) * inv_w, tv = (q.tv.a * x + v_row) * inv_w;
      const double lod =
          mipmapping ? 0.5 * FastLog2(static_cast<float>(q.det * inv_w * inv_w * inv_w)) : 0.0;
      c_row[x] = SampleTexture(texture, tu, tv, lod);
      z_row[x] = w;
      id_row[x] = q.surface;
    }
  }
}

}  // namespace

void RenderOptions::Check() const {
  EPILOC_CHECK(supersampling >= 1 && supersampling <= 8,
               "render options: supersampling = {} must be in [1, 8]", supersampling);
  EPILOC_CHECK(near_m > 0 && std::isfinite(near_m), "render options: near_m must be positive");
  EPILOC_CHECK(exposure_gain > 0 && std::isfinite(exposure_gain),
               "render options: exposure_gain must be positive");
  EPILOC_CHECK(noise_sigma >= 0 && std::isfinite(noise_sigma),
               "render options: noise_sigma must not be negative");
  EPILOC_CHECK(max_blur_taps >= 1, "render options: max_blur_taps must be >= 1");
  for (const double gain : white_balance_rgb) {
    EPILOC_CHECK(gain > 0 && std::isfinite(gain),
                 "render options: white balance gains must be positive, not {}", gain);
  }
}

cv::Vec3f SkyColour(const Eigen::Vector3d& direction_in_world) {
  const double up = direction_in_world.z() / direction_in_world.norm();
  const cv::Vec3f horizon(232, 220, 208), zenith(205, 145, 90), haze(205, 205, 200);
  if (up < 0) return horizon + (haze - horizon) * static_cast<float>(std::min(1.0, -up * 5));
  return horizon + (zenith - horizon) * static_cast<float>(std::pow(up, 0.6));
}

Renderer::Renderer(const Camera& camera, const RenderOptions& options)
    : camera_(camera), options_(options) {
  camera_.Check("render camera");
  options_.Check();
  rays_.create(camera_.height, camera_.width, CV_64FC2);
  for (int y = 0; y < camera_.height; ++y) {
    for (int x = 0; x < camera_.width; ++x) {
      const Eigen::Vector2d n = camera_.Unproject(Eigen::Vector2d(x, y));
      rays_.at<cv::Vec2d>(y, x) = cv::Vec2d(n.x(), n.y());
    }
  }
  pinhole_ = camera_;
  if (camera_.HasDistortion()) {
    // An undistorted camera with the same focal lengths whose image holds every ray of the
    // distorted one (pixel edges included), plus a margin for bilinear interpolation.
    double lo_x = 1e9, hi_x = -1e9, lo_y = 1e9, hi_y = -1e9;
    const auto extend = [&](double x, double y) {
      const Eigen::Vector2d n = camera_.Unproject(Eigen::Vector2d(x, y));
      lo_x = std::min(lo_x, n.x());
      hi_x = std::max(hi_x, n.x());
      lo_y = std::min(lo_y, n.y());
      hi_y = std::max(hi_y, n.y());
    };
    for (int x = 0; x <= camera_.width; ++x) {
      extend(x - 0.5, -0.5);
      extend(x - 0.5, camera_.height - 0.5);
    }
    for (int y = 0; y <= camera_.height; ++y) {
      extend(-0.5, y - 0.5);
      extend(camera_.width - 0.5, y - 0.5);
    }
    constexpr double kMarginPx = 3;
    pinhole_.distortion.fill(0.0);
    pinhole_.cx = -lo_x * camera_.fx + kMarginPx;
    pinhole_.cy = -lo_y * camera_.fy + kMarginPx;
    pinhole_.width = static_cast<int>(std::ceil((hi_x - lo_x) * camera_.fx + 2 * kMarginPx));
    pinhole_.height = static_cast<int>(std::ceil((hi_y - lo_y) * camera_.fy + 2 * kMarginPx));
    EPILOC_CHECK(pinhole_.width <= 4 * camera_.width && pinhole_.height <= 4 * camera_.height,
                 "render camera: distortion too strong to render ({}x{} undistorted pixels)",
                 pinhole_.width, pinhole_.height);
    map_x_.create(camera_.height, camera_.width, CV_32F);
    map_y_.create(camera_.height, camera_.width, CV_32F);
    for (int y = 0; y < camera_.height; ++y) {
      for (int x = 0; x < camera_.width; ++x) {
        const cv::Vec2d n = rays_.at<cv::Vec2d>(y, x);
        map_x_.at<float>(y, x) = static_cast<float>(pinhole_.fx * n[0] + pinhole_.cx);
        map_y_.at<float>(y, x) = static_cast<float>(pinhole_.fy * n[1] + pinhole_.cy);
      }
    }
  }
  supersampled_ = pinhole_.Scaled(options_.supersampling);
  if (options_.noise_sigma > 0) {
    // Prime sizes, so the tile's repetition does not line up with the image.
    noise_tile_.create(1031, 1327, CV_32FC3);
    cv::RNG rng(0x5EED);
    rng.fill(noise_tile_, cv::RNG::NORMAL, 0.0, options_.noise_sigma);
  }
}

RenderResult Renderer::Render(const World& world,
                              const Rigid3d& cam_from_world,
                              const std::optional<Rigid3d>& cam_from_world_exposure_end,
                              std::optional<uint64_t> noise_seed,
                              const RenderExtras& extras) const {
  const Camera& cam = supersampled_;
  const Eigen::Matrix3d r = cam_from_world.rotation.toRotationMatrix();
  const Eigen::Vector3d t = cam_from_world.translation;

  cv::Mat colour(cam.height, cam.width, CV_32FC3);
  cv::Mat inverse_depth(cam.height, cam.width, CV_64F, cv::Scalar(0));
  cv::Mat ids(cam.height, cam.width, CV_32S, cv::Scalar(-1));
  // The sky depends only on the elevation of the ray: sin(elevation) = (R^T ray).z / |ray|.
  static const std::vector<cv::Vec3f> kSky = [] {
    std::vector<cv::Vec3f> lut(kSkyTableSize + 1);
    for (int i = 0; i <= kSkyTableSize; ++i) {
      lut[i] = SkyColour(Eigen::Vector3d(0, std::sqrt(1 - Sq(SkyUp(i))), SkyUp(i)));
    }
    return lut;
  }();
  const Eigen::Vector3d up_in_cam = r.col(2);
  for (int y = 0; y < cam.height; ++y) {
    cv::Vec3f* row = colour.ptr<cv::Vec3f>(y);
    const double ry = (y - cam.cy) / cam.fy;
    for (int x = 0; x < cam.width; ++x) {
      const double rx = (x - cam.cx) / cam.fx;
      const double up = (up_in_cam.x() * rx + up_in_cam.y() * ry + up_in_cam.z()) /
                        std::sqrt(rx * rx + ry * ry + 1.0);
      row[x] = kSky[static_cast<int>((up + 1.0) * 0.5 * kSkyTableSize + 0.5)];
    }
  }
  std::vector<QuadSetup> quads;
  const int num_world = static_cast<int>(world.surfaces.size());
  const int num_extra = extras.surfaces ? static_cast<int>(extras.surfaces->size()) : 0;
  EPILOC_CHECK(num_extra == 0 || extras.textures, "render: extra surfaces without textures");
  EPILOC_CHECK(!extras.lighting || extras.lighting->num_world_surfaces() == num_world,
               "render: the lighting was built for another world ({} surfaces, not {})",
               extras.lighting ? extras.lighting->num_world_surfaces() : 0, num_world);
  std::vector<Eigen::Vector3d> inverse_depth_of(num_world + num_extra, Eigen::Vector3d::Zero());
  for (int i = 0; i < num_world + num_extra; ++i) {
    const Surface& s = i < num_world ? world.surfaces[i] : (*extras.surfaces)[i - num_world];
    if (s.texture < 0) continue;
    const Texture& texture =
        i < num_world ? world.textures[s.texture] : extras.textures->at(s.texture);
    QuadSetup q;
    if (!SetUpQuad(s, texture, i, cam, r, t, options_.near_m, &q)) continue;
    // The ground lies under everything: drawn last, it is mostly rejected by the depth test.
    if (s.kind == SurfaceKind::kGround) q.nearest_z = std::numeric_limits<double>::infinity();
    quads.push_back(q);
    const Eigen::Vector3d n = r * s.Normal();
    inverse_depth_of[i] = n / (s.PlaneOffset() + n.dot(t));
  }
  // Front to back, so hidden pixels fail the depth test before any texture lookup.
  std::sort(quads.begin(), quads.end(),
            [](const QuadSetup& a, const QuadSetup& b) { return a.nearest_z < b.nearest_z; });
  for (const QuadSetup& q : quads) {
    Rasterise(q, options_.mipmapping, colour, inverse_depth, ids);
  }
  if (extras.lighting) {
    extras.lighting->Shade(cam, cam_from_world, extras.surfaces, ids, inverse_depth, &colour);
  }

  if (options_.supersampling > 1) {
    cv::resize(colour, colour, cv::Size(pinhole_.width, pinhole_.height), 0, 0, cv::INTER_AREA);
  }
  if (!map_x_.empty()) {
    cv::remap(colour, colour, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  }

  RenderResult result;
  const bool blur = cam_from_world_exposure_end.has_value();
  const bool need_depth = options_.depth || options_.surface_ids || blur;
  cv::Mat depth, out_ids;
  if (need_depth) {
    // Exact per output pixel: the surface seen by the nearest render sample, intersected with the
    // pixel's own ray.
    depth.create(camera_.height, camera_.width, CV_32F);
    out_ids.create(camera_.height, camera_.width, CV_32S);
    for (int y = 0; y < camera_.height; ++y) {
      for (int x = 0; x < camera_.width; ++x) {
        const cv::Vec2d n = rays_.at<cv::Vec2d>(y, x);
        const int sx = static_cast<int>(std::floor(cam.fx * n[0] + cam.cx + 0.5));
        const int sy = static_cast<int>(std::floor(cam.fy * n[1] + cam.cy + 0.5));
        int id = -1;
        if (sx >= 0 && sy >= 0 && sx < cam.width && sy < cam.height) id = ids.at<int>(sy, sx);
        float z = 0;
        if (id >= 0) {
          const double w = inverse_depth_of[id].dot(Eigen::Vector3d(n[0], n[1], 1.0));
          if (w > 0) z = static_cast<float>(1.0 / w);
        }
        depth.at<float>(y, x) = z;
        out_ids.at<int>(y, x) = z > 0 ? id : -1;
      }
    }
  }
  if (blur) {
    const Rigid3d end_from_mid = *cam_from_world_exposure_end * cam_from_world.Inverse();
    const Eigen::Matrix3d rotation = end_from_mid.rotation.toRotationMatrix();
    const Eigen::Vector3d translation = end_from_mid.translation;
    const cv::Mat sharp = colour.clone();
    for (int y = 0; y < camera_.height; ++y) {
      for (int x = 0; x < camera_.width; ++x) {
        const cv::Vec2d n = rays_.at<cv::Vec2d>(y, x);
        const float z = depth.at<float>(y, x);
        // Sky is at infinity: only the rotation moves it.
        const Eigen::Vector3d p(n[0], n[1], 1.0);
        const Eigen::Vector3d moved = z > 0 ? Eigen::Vector3d(rotation * (z * p) + translation)
                                            : Eigen::Vector3d(rotation * p);
        if (moved.z() <= 1e-6) continue;
        // Image motion from the change of normalised coordinates; the lens distortion's local
        // scale is left out (a blur kernel need not be exact).
        const Eigen::Vector2d flow(camera_.fx * (moved.x() / moved.z() - n[0]),
                                   camera_.fy * (moved.y() / moved.z() - n[1]));
        // Samples at most ~1.3 px apart along the path from -flow to +flow (bilinear sampling
        // fills the gaps).
        const double length = flow.norm();
        if (length < 0.25) continue;
        const int taps = std::min(options_.max_blur_taps, 2 + static_cast<int>(0.75 * length));
        cv::Vec3f sum(0, 0, 0);
        for (int k = 0; k < taps; ++k) {
          const double f = 2.0 * k / (taps - 1) - 1.0;
          sum += BilinearF(sharp, x + f * flow.x(), y + f * flow.y());
        }
        colour.at<cv::Vec3f>(y, x) = sum / static_cast<float>(taps);
      }
    }
  }
  if (options_.exposure_gain != 1.0) colour *= options_.exposure_gain;
  const std::array<double, 3>& wb = options_.white_balance_rgb;
  if (wb[0] != 1.0 || wb[1] != 1.0 || wb[2] != 1.0) {
    colour = colour.mul(cv::Scalar(wb[2], wb[1], wb[0]));  // BGR
  }
  if (options_.noise_sigma > 0) {
    // A window of the renderer's noise tile at a random offset: Gaussian per pixel, and much
    // cheaper than drawing new numbers for every frame.
    Rng rng(noise_seed.value_or(options_.noise_seed));
    const int ox = rng.UniformInt(0, noise_tile_.cols - 1),
              oy = rng.UniformInt(0, noise_tile_.rows - 1);
    for (int y = 0; y < colour.rows; ++y) {
      cv::Vec3f* row = colour.ptr<cv::Vec3f>(y);
      const cv::Vec3f* noise = noise_tile_.ptr<cv::Vec3f>((y + oy) % noise_tile_.rows);
      for (int x = 0; x < colour.cols; ++x) row[x] += noise[(x + ox) % noise_tile_.cols];
    }
  }
  colour.convertTo(result.image, CV_8UC3);
  if (options_.depth) result.depth = depth;
  if (options_.surface_ids) result.surface_id = out_ids;
  return result;
}

}  // namespace epiloc
