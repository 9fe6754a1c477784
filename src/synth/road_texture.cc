// Road, pavement and ground textures evaluated per texel from world and road coordinates, so that
// markings and noise continue across the many quads that tile a curved road.
#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "draw_util.h"
#include "epiloc/synth/texture.h"

namespace epiloc {
namespace {

using synth_internal::Px;

double Clamp01(double x) { return std::min(1.0, std::max(0.0, x)); }

// Coverage of a texel `texel` metres wide whose centre lies `distance` from the middle of a
// stripe of half width `half` (box-filtered, so thin lines do not alias).
double Stripe(double distance, double half, double texel) {
  return Clamp01((half + 0.5 * texel - std::abs(distance)) / texel);
}

// Coverage of the "on" part [0, on) of a pattern repeating every `period` metres.
double Dash(double x, double period, double on, double texel) {
  const double m = x - period * std::floor(x / period);
  const double distance = std::min(std::abs(m - 0.5 * on), std::abs(m - period - 0.5 * on));
  return Stripe(distance, 0.5 * on, texel);
}

cv::Vec3b Grey(double g, double tint_b = 0, double tint_r = 0) {
  return cv::Vec3b(cv::saturate_cast<uchar>(g + tint_b), cv::saturate_cast<uchar>(g),
                   cv::saturate_cast<uchar>(g + tint_r));
}

cv::Vec3b Blend(const cv::Vec3b& a, const cv::Vec3b& b, double t) {
  cv::Vec3b out;
  for (int c = 0; c < 3; ++c) out[c] = cv::saturate_cast<uchar>(a[c] + (b[c] - a[c]) * t);
  return out;
}

double StampAlpha(const RoadStamp& stamp, double s, double d) {
  if (s < stamp.s0_m || s >= stamp.s1_m || d < stamp.d0_m || d >= stamp.d1_m) return 0.0;
  const double x = (stamp.d1_m - d) / (stamp.d1_m - stamp.d0_m) * stamp.alpha.cols - 0.5;
  const double y = (stamp.s1_m - s) / (stamp.s1_m - stamp.s0_m) * stamp.alpha.rows - 0.5;
  const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, stamp.alpha.cols - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, stamp.alpha.rows - 1);
  const int x1 = std::min(x0 + 1, stamp.alpha.cols - 1),
            y1 = std::min(y0 + 1, stamp.alpha.rows - 1);
  const double fx = Clamp01(x - x0), fy = Clamp01(y - y0);
  const auto a = [&](int yy, int xx) { return stamp.alpha.at<uchar>(yy, xx) / 255.0; };
  return (a(y0, x0) * (1 - fx) + a(y0, x1) * fx) * (1 - fy) +
         (a(y1, x0) * (1 - fx) + a(y1, x1) * fx) * fy;
}

// Calls colour(x_world, y_world, texel_colour&) for every texel of the patch, rows in parallel.
template <typename ColourFn>
Texture EvaluateTexels(cv::Size size, double mpp, const GroundPatch& patch, ColourFn colour) {
  Texture texture;
  texture.metres_per_pixel = mpp;
  texture.image.create(size, CV_8UC3);
  for (int y = 0; y < size.height; ++y) {
    cv::Vec3b* row = texture.image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size.width; ++x) {
      const Eigen::Vector2d p =
          patch.origin_in_world + (x + 0.5) * mpp * patch.u_axis + (y + 0.5) * mpp * patch.v_axis;
      row[x] = colour(p);
    }
  }
  return texture;
}

}  // namespace

Texture RoadTexture(cv::Size size,
                    double metres_per_pixel,
                    const GroundPatch& patch,
                    const Centreline& centreline,
                    const RoadProfile& profile,
                    const std::vector<RoadStamp>& stamps,
                    const std::vector<double>& crossings_s_m,
                    uint64_t seed) {
  const double lane = profile.lane_width_m, half = profile.asphalt_half_width_m();
  const cv::Vec3b paint_bgr(222, 226, 226);
  return EvaluateTexels(size, metres_per_pixel, patch, [&](const Eigen::Vector2d& p) {
    const RoadCoordinates rc = centreline.ToRoadOnPiece(p, patch.piece);
    const double s = rc.s_m, d = rc.d_m, ad = std::abs(d);
    // Asphalt: grain, mottling, darker wheel tracks, repair patches with sharp outlines.
    double g = 88 + 34 * (FractalNoise(p.x() / 3.0, p.y() / 3.0, 3, seed) - 0.5) +
               14 * (ValueNoise(p.x() / 0.12, p.y() / 0.12, seed + 1) - 0.5) +
               22 * (CellHash(static_cast<int64_t>(std::floor(p.x() / 0.018)),
                              static_cast<int64_t>(std::floor(p.y() / 0.018)), seed + 2) -
                     0.5);
    for (const double track : {lane / 2 - 0.85, lane / 2 + 0.85}) {
      const double t = (ad - track) / 0.35;
      if (ad < lane) g -= 9 * std::exp(-t * t);
    }
    if (FractalNoise(p.x() / 9.0, p.y() / 9.0, 2, seed + 3) > 0.7) g -= 17;
    const double tx = metres_per_pixel;
    cv::Vec3b colour = Grey(g, 3, -2);
    // Concrete gutter slabs along the kerb.
    const double gutter = Clamp01((ad - (half - 0.3)) / tx + 0.5);
    if (gutter > 0) {
      const double slab =
          150 + 20 * (CellHash(static_cast<int64_t>(std::floor(s / 0.5)), d > 0, seed + 4) - 0.5);
      const cv::Vec3b concrete = Grey(slab - 60 * Dash(s, 0.5, 0.012, tx) + 0.3 * (g - 88));
      colour = Blend(colour, concrete, gutter);
    }
    // Markings, worn by noise.
    double paint =
        std::max(Stripe(d, 0.06, tx) * Dash(s, 9.0, 3.0, tx), Stripe(ad - lane, 0.06, tx));
    bool near_crossing = false;
    for (const double sc : crossings_s_m) {
      near_crossing = near_crossing || (s > sc - 8 && s < sc + 12);
      if (s > sc - 0.1 && s < sc + 4.1 && ad < lane) {
        paint = Stripe(s - sc - 2.0, 2.0, tx) * Dash(d + 50.25, 1.0, 0.5, tx);
      }
      if (d < -0.1 && d > -lane) paint = std::max(paint, Stripe(s - sc + 1.35, 0.15, tx));
      if (d > 0.1 && d < lane) paint = std::max(paint, Stripe(s - sc - 5.35, 0.15, tx));
    }
    if (!near_crossing && ad > lane && ad < half - 0.4) {
      paint = std::max(paint, Dash(s + 2.0, 5.5, 0.12, tx));
    }
    const double wear =
        Clamp01(0.55 + 1.2 * (ValueNoise(p.x() / 0.25, p.y() / 0.25, seed + 5) - 0.3));
    if (paint > 0) colour = Blend(colour, paint_bgr, paint * wear);
    // Stamps whose s-range may hold s (stamps are at most 8 m long).
    auto it = std::lower_bound(stamps.begin(), stamps.end(), s - 8.0,
                               [](const RoadStamp& st, double v) { return st.s0_m < v; });
    for (; it != stamps.end() && it->s0_m <= s; ++it) {
      const double a = StampAlpha(*it, s, d);
      if (a > 0) colour = Blend(colour, it->bgr, a * (it->bgr[0] > 150 ? wear : 1.0));
    }
    return colour;
  });
}

Texture SidewalkTexture(cv::Size size,
                        double metres_per_pixel,
                        const GroundPatch& patch,
                        const Centreline& centreline,
                        const RoadProfile& profile,
                        uint64_t seed) {
  const double half = profile.asphalt_half_width_m();
  return EvaluateTexels(size, metres_per_pixel, patch, [&](const Eigen::Vector2d& p) {
    const RoadCoordinates rc = centreline.ToRoadOnPiece(p, patch.piece);
    const double s = rc.s_m, dd = std::abs(rc.d_m) - half, side = rc.d_m > 0 ? 1 : 0;
    const double dirt = 30 * (FractalNoise(p.x() / 2.0, p.y() / 2.0, 4, seed) - 0.5) +
                        16 * (CellHash(static_cast<int64_t>(std::floor(p.x() / 0.02)),
                                       static_cast<int64_t>(std::floor(p.y() / 0.02)), seed + 1) -
                              0.5);
    const double tx = metres_per_pixel;
    // Kerb stones (1 m long) along the road edge, small pavers, then large slabs.
    const double kerb = Clamp01((0.3 - dd) / tx + 0.5);
    const double kerb_grey = 170 - 80 * Dash(s + 0.0075, 1.0, 0.015, tx) + 0.5 * dirt;
    const double stone = dd < 4.3 ? 0.3 : 0.6;
    const double a = s / stone, b = (dd - 0.3) / stone;
    const double shift = dd < 4.3 ? 0.0 : 0.5 * std::fmod(std::abs(std::floor(b)), 2.0);
    const double fa = a + shift - std::floor(a + shift), fb = b - std::floor(b);
    const double joint = std::max(Stripe(std::min(fa, 1 - fa) * stone, 0.007, tx),
                                  Stripe(std::min(fb, 1 - fb) * stone, 0.007, tx));
    const double h =
        CellHash(static_cast<int64_t>(std::floor(a + shift)),
                 static_cast<int64_t>(std::floor(b)) * 2 + static_cast<int>(side), seed + 2);
    const cv::Vec3b paver = h < 0.04 ? Grey(120 + 0.6 * dirt, -30, 25)  // a reddish stone
                                     : Grey(135 + 40 * (h - 0.5) + dirt, 4, 0);
    return Blend(Blend(paver, Grey(70 + 0.5 * dirt), joint), Grey(kerb_grey), kerb);
  });
}

Texture GroundTexture(cv::Size size,
                      double metres_per_pixel,
                      const GroundPatch& patch,
                      uint64_t seed) {
  const cv::Vec3b grass(60, 120, 80), soil(70, 95, 120);
  return EvaluateTexels(size, metres_per_pixel, patch, [&](const Eigen::Vector2d& p) {
    const double mix = Clamp01(1.6 * (FractalNoise(p.x() / 25.0, p.y() / 25.0, 3, seed) - 0.3));
    const double shade = 0.75 + 0.5 * FractalNoise(p.x() / 2.0, p.y() / 2.0, 4, seed + 1) +
                         0.2 * (CellHash(static_cast<int64_t>(std::floor(p.x() / 0.1)),
                                         static_cast<int64_t>(std::floor(p.y() / 0.1)), seed + 2) -
                                0.5);
    const cv::Vec3b c = Blend(grass, soil, mix);
    return cv::Vec3b(cv::saturate_cast<uchar>(c[0] * shade), cv::saturate_cast<uchar>(c[1] * shade),
                     cv::saturate_cast<uchar>(c[2] * shade));
  });
}

Texture KerbTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed) {
  Rng rng(seed);
  Texture texture;
  texture.metres_per_pixel = 1.0 / pixels_per_m;
  texture.image.create(std::max(2, Px(height_m, pixels_per_m)),
                       std::max(2, Px(width_m, pixels_per_m)), CV_8UC3);
  texture.image.setTo(cv::Scalar(150, 152, 152));
  for (int x = 0; x < texture.image.cols; x += Px(1.0, pixels_per_m)) {
    cv::line(texture.image, {x, 0}, {x, texture.image.rows}, cv::Scalar(80, 80, 80));
  }
  ModulateByNoise(texture.image, 0.2 * pixels_per_m, 3, 0.4, rng);
  return texture;
}

std::vector<RoadStamp> MakeRoadStamps(double s_begin_m,
                                      double s_end_m,
                                      const RoadProfile& profile,
                                      uint64_t seed) {
  Rng rng(seed);
  const double lane = profile.lane_width_m, half = profile.asphalt_half_width_m();
  std::vector<RoadStamp> stamps;
  for (double s = s_begin_m + rng.Uniform(5, 15); s < s_end_m - 10; s += rng.Uniform(6, 14)) {
    RoadStamp st;
    const double kind = rng.Uniform();
    const bool right = rng.Bernoulli(0.5);
    if (kind < 0.25) {  // lane text or arrow, readable by the lane's drivers
      st.s0_m = s;
      st.s1_m = s + rng.Uniform(2.5, 4.0);
      st.d0_m = right ? -lane + 0.6 : 0.6;
      st.d1_m = right ? -0.6 : lane - 0.6;
      st.alpha = cv::Mat(60, 120, CV_8U, cv::Scalar(0));
      if (rng.Bernoulli(0.6)) {
        static const char* kTexts[] = {"BUS", "30", "STOP", "TAXI", "BIKE", "SLOW", "50"};
        synth_internal::DrawTextFit(st.alpha, kTexts[rng.UniformInt(0, 6)],
                                    cv::Rect(0, 0, st.alpha.cols, st.alpha.rows), cv::Scalar(255),
                                    rng);
      } else {
        synth_internal::DrawGlyph(st.alpha, cv::Rect(30, 0, 60, 60), cv::Scalar(255), rng);
      }
      if (!right) cv::rotate(st.alpha, st.alpha, cv::ROTATE_180);
      st.bgr = cv::Vec3b(222, 226, 226);
    } else if (kind < 0.5) {  // manhole cover
      const double r = rng.Uniform(0.3, 0.4), d = rng.Uniform(-lane + 0.5, lane - 0.5);
      st.s0_m = s - r;
      st.s1_m = s + r;
      st.d0_m = d - r;
      st.d1_m = d + r;
      st.alpha = cv::Mat(64, 64, CV_8U, cv::Scalar(0));
      cv::circle(st.alpha, {32, 32}, 31, cv::Scalar(255), cv::FILLED, cv::LINE_AA);
      for (int k = 4; k < 64; k += 8) {
        cv::line(st.alpha, {k, 0}, {k, 63}, cv::Scalar(120), 2);
        cv::line(st.alpha, {0, k}, {63, k}, cv::Scalar(120), 2);
      }
      cv::circle(st.alpha, {32, 32}, 31, cv::Scalar(0), 3, cv::LINE_AA);
      cv::circle(st.alpha, {32, 32}, 26, cv::Scalar(255), 3, cv::LINE_AA);
      st.bgr = cv::Vec3b(45, 48, 52);
    } else if (kind < 0.75) {  // repair patch
      const double w = rng.Uniform(0.6, 2.5), l = rng.Uniform(0.8, 3.5);
      const double d = rng.Uniform(-half + 0.5 + w / 2, half - 0.5 - w / 2);
      st.s0_m = s;
      st.s1_m = s + l;
      st.d0_m = d - w / 2;
      st.d1_m = d + w / 2;
      st.alpha = cv::Mat(8, 8, CV_8U, cv::Scalar(230));
      st.bgr = rng.Bernoulli(0.5) ? cv::Vec3b(55, 55, 55) : cv::Vec3b(105, 105, 100);
    } else {  // crack
      const double l = rng.Uniform(2.0, 5.0), d = rng.Uniform(-half + 1, half - 1.5);
      st.s0_m = s;
      st.s1_m = s + l;
      st.d0_m = d;
      st.d1_m = d + 1.2;
      st.alpha = cv::Mat(Px(l, 40), 48, CV_8U, cv::Scalar(0));
      cv::Point p(rng.UniformInt(10, 38), 0);
      std::vector<cv::Point> pts;
      while (p.y < st.alpha.rows) {
        pts.push_back(p);
        p += cv::Point(rng.UniformInt(-4, 4), rng.UniformInt(2, 6));
        p.x = std::clamp(p.x, 2, 45);
      }
      cv::polylines(st.alpha, pts, false, cv::Scalar(255), 1, cv::LINE_AA);
      st.bgr = cv::Vec3b(30, 30, 30);
    }
    stamps.push_back(st);
  }
  std::sort(stamps.begin(), stamps.end(),
            [](const RoadStamp& a, const RoadStamp& b) { return a.s0_m < b.s0_m; });
  return stamps;
}

}  // namespace epiloc
