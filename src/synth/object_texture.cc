// Textures of street furniture and cars, and the drawing helpers of draw_util.h.
#include <algorithm>
#include <array>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "draw_util.h"
#include "epiloc/synth/texture.h"

namespace epiloc {
namespace synth_internal {

cv::Vec3b Jitter(const cv::Vec3b& bgr, double amount, Rng& rng) {
  const double brightness = 1.0 + amount * (2 * rng.Uniform() - 1);
  cv::Vec3b out;
  for (int c = 0; c < 3; ++c) {
    const double hue = 1.0 + 0.3 * amount * (2 * rng.Uniform() - 1);
    out[c] = cv::saturate_cast<uchar>(bgr[c] * brightness * hue);
  }
  return out;
}

cv::Scalar ToScalar(const cv::Vec3b& bgr) { return cv::Scalar(bgr[0], bgr[1], bgr[2]); }

cv::Vec3b WallColour(Rng& rng) {
  static const std::array<cv::Vec3b, 8> kPalette = {
      cv::Vec3b(170, 200, 225), cv::Vec3b(150, 170, 190), cv::Vec3b(200, 205, 210),
      cv::Vec3b(120, 160, 200), cv::Vec3b(180, 190, 170), cv::Vec3b(110, 130, 150),
      cv::Vec3b(140, 180, 215), cv::Vec3b(205, 215, 230)};
  return Jitter(kPalette[rng.UniformInt(0, kPalette.size() - 1)], 0.12, rng);
}

cv::Vec3b BrightColour(Rng& rng) {
  static const std::array<cv::Vec3b, 10> kPalette = {
      cv::Vec3b(40, 40, 200),  cv::Vec3b(200, 90, 30),  cv::Vec3b(40, 170, 40),
      cv::Vec3b(30, 200, 230), cv::Vec3b(160, 40, 150), cv::Vec3b(230, 230, 230),
      cv::Vec3b(30, 30, 30),   cv::Vec3b(0, 120, 240),  cv::Vec3b(150, 150, 20),
      cv::Vec3b(90, 30, 120)};
  return Jitter(kPalette[rng.UniformInt(0, kPalette.size() - 1)], 0.15, rng);
}

std::string RandomWord(Rng& rng) {
  static const std::array<const char*, 24> kWords = {
      "BAECKEREI", "CAFE",  "APOTHEKE", "HOTEL", "PIZZA",  "BUCHLADEN", "FRISEUR", "BANK",
      "KIOSK",     "OPTIK", "BISTRO",   "MARKT", "BLUMEN", "SHOP",      "BAR",     "DELI",
      "METZGEREI", "TABAK", "MODE",     "SPORT", "POST",   "DOENER",    "ASIA",    "FOTO"};
  return kWords[rng.UniformInt(0, kWords.size() - 1)];
}

std::string RandomNumberText(Rng& rng) {
  std::string text;
  for (int i = rng.UniformInt(1, 3); i > 0; --i)
    text += static_cast<char>('A' + rng.UniformInt(0, 25));
  text += "-" + std::to_string(rng.UniformInt(1, 999));
  return text;
}

void DrawTextFit(cv::Mat& image,
                 const std::string& text,
                 const cv::Rect& box,
                 const cv::Scalar& colour,
                 Rng& rng) {
  if (box.width < 4 || box.height < 4 || text.empty()) return;
  static const std::array<int, 5> kFonts = {cv::FONT_HERSHEY_SIMPLEX, cv::FONT_HERSHEY_DUPLEX,
                                            cv::FONT_HERSHEY_COMPLEX, cv::FONT_HERSHEY_TRIPLEX,
                                            cv::FONT_HERSHEY_PLAIN};
  int font = kFonts[rng.UniformInt(0, kFonts.size() - 1)];
  if (rng.Bernoulli(0.2)) font |= cv::FONT_ITALIC;
  int baseline = 0;
  const cv::Size unit = cv::getTextSize(text, font, 1.0, 1, &baseline);
  const double scale = std::min(box.width * 0.95 / unit.width, box.height * 0.8 / unit.height);
  const int thickness = std::max(1, static_cast<int>(scale * rng.Uniform(1.2, 2.5)));
  const cv::Size size = cv::getTextSize(text, font, scale, thickness, &baseline);
  const cv::Point origin(box.x + (box.width - size.width) / 2,
                         box.y + (box.height + size.height) / 2);
  cv::putText(image, text, origin, font, scale, colour, thickness, cv::LINE_AA);
}

void DrawGlyph(cv::Mat& image, const cv::Rect& box, const cv::Scalar& colour, Rng& rng) {
  const cv::Point2d c(box.x + box.width / 2.0, box.y + box.height / 2.0);
  const double r = std::min(box.width, box.height) / 2.0;
  const int kind = rng.UniformInt(0, 3);
  const int thickness = std::max(1, static_cast<int>(r / 5));
  if (kind == 0 || kind == 1) {
    // Random star-like or convex polygon.
    const int n = rng.UniformInt(3, 8);
    std::vector<cv::Point> pts;
    for (int i = 0; i < 2 * n; ++i) {
      const double a = M_PI * i / n + 0.3 * rng.Uniform();
      const double rr = (kind == 0 && i % 2) ? r * rng.Uniform(0.35, 0.6) : r * 0.95;
      pts.emplace_back(c + cv::Point2d(rr * std::cos(a), rr * std::sin(a)));
    }
    cv::fillPoly(image, std::vector<std::vector<cv::Point>>{pts}, colour, cv::LINE_AA);
  } else if (kind == 2) {
    cv::circle(image, c, static_cast<int>(r * 0.9), colour, thickness, cv::LINE_AA);
    cv::circle(image, c, static_cast<int>(r * 0.35), colour, cv::FILLED, cv::LINE_AA);
    cv::line(image, c + cv::Point2d(-r * 0.9, 0), c + cv::Point2d(r * 0.9, 0), colour, thickness);
  } else {
    // Arrow.
    const double a = rng.UniformInt(0, 3) * M_PI / 2;
    const cv::Point2d d(std::cos(a), std::sin(a)), n(-d.y, d.x);
    std::vector<cv::Point> pts = {c - d * r * 0.9 + n * r * 0.2, c + d * r * 0.1 + n * r * 0.2,
                                  c + d * r * 0.1 + n * r * 0.6, c + d * r * 0.9,
                                  c + d * r * 0.1 - n * r * 0.6, c + d * r * 0.1 - n * r * 0.2,
                                  c - d * r * 0.9 - n * r * 0.2};
    cv::fillPoly(image, std::vector<std::vector<cv::Point>>{pts}, colour, cv::LINE_AA);
  }
}

void DrawPoster(cv::Mat& image, const cv::Rect& box, Rng& rng) {
  const cv::Rect clipped = box & cv::Rect(0, 0, image.cols, image.rows);
  if (clipped.width < 6 || clipped.height < 6) return;
  cv::rectangle(image, clipped, ToScalar(BrightColour(rng)), cv::FILLED);
  for (int i = rng.UniformInt(1, 3); i > 0; --i) {
    const int s = std::max(3, clipped.width / rng.UniformInt(2, 4));
    DrawGlyph(image,
              cv::Rect(clipped.x + rng.UniformInt(0, clipped.width - s),
                       clipped.y + rng.UniformInt(0, std::max(0, clipped.height / 2 - s)), s, s),
              ToScalar(BrightColour(rng)), rng);
  }
  DrawTextFit(
      image, RandomWord(rng),
      cv::Rect(clipped.x, clipped.y + clipped.height * 3 / 5, clipped.width, clipped.height / 5),
      ToScalar(BrightColour(rng)), rng);
  DrawTextFit(
      image, RandomNumberText(rng),
      cv::Rect(clipped.x, clipped.y + clipped.height * 4 / 5, clipped.width, clipped.height / 6),
      cv::Scalar(20, 20, 20), rng);
}

}  // namespace synth_internal

using synth_internal::Jitter;
using synth_internal::Px;
using synth_internal::ToScalar;

Texture SignTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed) {
  Rng rng(seed);
  Texture texture;
  texture.metres_per_pixel = 1.0 / pixels_per_m;
  cv::Mat& image = texture.image;
  image.create(Px(height_m, pixels_per_m), Px(width_m, pixels_per_m), CV_8UC3);
  image.setTo(cv::Scalar(150, 150, 150));
  const cv::Rect full(0, 0, image.cols, image.rows);
  const cv::Point c(image.cols / 2, image.rows / 2);
  const int r = std::min(image.cols, image.rows) / 2 - 1;
  const int border = std::max(2, r / 6);
  switch (rng.UniformInt(0, 4)) {
    case 0:  // speed limit
      cv::circle(image, c, r, cv::Scalar(245, 245, 245), cv::FILLED, cv::LINE_AA);
      cv::circle(image, c, r - border / 2, cv::Scalar(30, 30, 210), border, cv::LINE_AA);
      synth_internal::DrawTextFit(image, std::to_string(10 * rng.UniformInt(2, 8)),
                                  cv::Rect(c.x - r / 2, c.y - r / 2, r, r), cv::Scalar(10, 10, 10),
                                  rng);
      break;
    case 1: {  // warning triangle with a glyph
      const std::vector<cv::Point> tri = {
          {c.x, c.y - r}, {c.x + r, c.y + r * 3 / 4}, {c.x - r, c.y + r * 3 / 4}};
      cv::fillConvexPoly(image, tri, cv::Scalar(30, 30, 210), cv::LINE_AA);
      std::vector<cv::Point> inner;
      for (const cv::Point& p : tri) inner.push_back(c + (p - c) * 0.7);
      cv::fillConvexPoly(image, inner, cv::Scalar(240, 240, 240), cv::LINE_AA);
      synth_internal::DrawGlyph(image, cv::Rect(c.x - r / 3, c.y - r / 6, 2 * r / 3, 2 * r / 3),
                                cv::Scalar(10, 10, 10), rng);
      break;
    }
    case 2:  // blue information sign
      image.setTo(cv::Scalar(170, 80, 20));
      cv::rectangle(image, full, cv::Scalar(240, 240, 240), border);
      synth_internal::DrawGlyph(image, cv::Rect(border * 2, border * 2, r, r),
                                cv::Scalar(240, 240, 240), rng);
      synth_internal::DrawTextFit(
          image, synth_internal::RandomWord(rng),
          cv::Rect(border, image.rows * 2 / 3, image.cols - 2 * border, image.rows / 4),
          cv::Scalar(240, 240, 240), rng);
      break;
    case 3:  // street name / direction sign with text lines
      image.setTo(rng.Bernoulli(0.5) ? cv::Scalar(40, 200, 240) : cv::Scalar(240, 240, 240));
      cv::rectangle(image, full, cv::Scalar(20, 20, 20), border);
      for (int i = 0; i < 3; ++i) {
        synth_internal::DrawTextFit(
            image, synth_internal::RandomWord(rng) + "STR",
            cv::Rect(border * 2, border + i * (image.rows - 2 * border) / 3,
                     image.cols - 4 * border, (image.rows - 2 * border) / 3),
            cv::Scalar(20, 20, 20), rng);
      }
      break;
    default:  // advertisement
      synth_internal::DrawPoster(image, full, rng);
      break;
  }
  return texture;
}

Texture MetalTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed) {
  Rng rng(seed);
  Texture texture;
  texture.metres_per_pixel = 1.0 / pixels_per_m;
  texture.image.create(std::max(2, Px(height_m, pixels_per_m)),
                       std::max(2, Px(width_m, pixels_per_m)), CV_8UC3);
  texture.image.setTo(ToScalar(Jitter(cv::Vec3b(120, 125, 125), 0.2, rng)));
  synth_internal::DrawPoster(
      texture.image,
      cv::Rect(0, texture.image.rows / 3, texture.image.cols, texture.image.cols * 2), rng);
  ModulateByNoise(texture.image, 0.3 * pixels_per_m, 3, 0.3, rng);
  return texture;
}

Texture CarTexture(int face,
                   double width_m,
                   double height_m,
                   double pixels_per_m,
                   const cv::Vec3b& body_bgr,
                   uint64_t seed) {
  Rng rng(seed);
  const double ppm = pixels_per_m;
  Texture texture;
  texture.metres_per_pixel = 1.0 / ppm;
  cv::Mat& image = texture.image;
  image.create(Px(height_m, ppm), Px(width_m, ppm), CV_8UC3);
  image.setTo(ToScalar(body_bgr));
  const int w = image.cols, h = image.rows;
  const cv::Scalar glass(45, 35, 30), dark(25, 25, 25), chrome(190, 195, 200);
  const int line = std::max(1, Px(0.02, ppm));
  if (face == 0) {  // side: windows, doors, wheels
    const int top = h * 38 / 100;
    const std::vector<cv::Point> windows = {{w * 22 / 100, h * 4 / 100},
                                            {w * 75 / 100, h * 4 / 100},
                                            {w * 86 / 100, top},
                                            {w * 12 / 100, top}};
    cv::fillConvexPoly(image, windows, glass, cv::LINE_AA);
    for (const int x : {w * 47 / 100, w * 62 / 100}) {
      cv::line(image, {x, h * 4 / 100}, {x, h * 80 / 100}, body_bgr * 0.55, line * 2);
    }
    cv::line(image, {w * 30 / 100, top}, {w * 30 / 100, h * 80 / 100}, body_bgr * 0.55, line);
    for (const int x : {w * 40 / 100, w * 56 / 100}) {
      cv::rectangle(image, cv::Rect(x, top + h / 10, w / 25, h / 30 + 1), chrome, cv::FILLED);
    }
    cv::line(image, {0, h * 55 / 100}, {w, h * 55 / 100}, body_bgr * 0.7, line);
    const int r = Px(0.32, ppm);
    for (const int x : {Px(0.8, ppm), w - Px(0.8, ppm)}) {
      cv::circle(image, {x, h - r}, r + Px(0.06, ppm), body_bgr * 0.3, cv::FILLED, cv::LINE_AA);
      cv::circle(image, {x, h - r}, r, dark, cv::FILLED, cv::LINE_AA);
      cv::circle(image, {x, h - r}, r * 6 / 10, chrome, cv::FILLED, cv::LINE_AA);
      for (int k = 0; k < 5; ++k) {
        const double a = 2 * M_PI * k / 5 + rng.Uniform();
        cv::line(image, {x, h - r},
                 {x + static_cast<int>(r * 0.6 * std::cos(a)),
                  h - r + static_cast<int>(r * 0.6 * std::sin(a))},
                 dark, line * 2, cv::LINE_AA);
      }
    }
  } else if (face == 1 || face == 2) {  // front / back
    const bool front = face == 1;
    const std::vector<cv::Point> screen = {{w * 15 / 100, h * 5 / 100},
                                           {w * 85 / 100, h * 5 / 100},
                                           {w * 93 / 100, h * 38 / 100},
                                           {w * 7 / 100, h * 38 / 100}};
    cv::fillConvexPoly(image, screen, glass, cv::LINE_AA);
    const cv::Scalar light = front ? cv::Scalar(220, 235, 240) : cv::Scalar(30, 30, 200);
    for (const int x : {w * 5 / 100, w * 75 / 100}) {
      cv::rectangle(image, cv::Rect(x, h * 48 / 100, w * 20 / 100, h * 12 / 100), light, cv::FILLED,
                    cv::LINE_AA);
    }
    if (front) {
      const cv::Rect grille(w * 30 / 100, h * 48 / 100, w * 40 / 100, h * 14 / 100);
      cv::rectangle(image, grille, dark, cv::FILLED);
      for (int y = grille.y + 2; y < grille.y + grille.height; y += 3) {
        cv::line(image, {grille.x, y}, {grille.x + grille.width - 1, y}, chrome * 0.6);
      }
    }
    cv::rectangle(image, cv::Rect(0, h * 78 / 100, w, h * 22 / 100), body_bgr * 0.4, cv::FILLED);
    const cv::Rect plate(w * 32 / 100, h * 66 / 100, w * 36 / 100, h * 11 / 100);
    cv::rectangle(image, plate, cv::Scalar(235, 235, 235), cv::FILLED);
    cv::rectangle(image, cv::Rect(plate.x, plate.y, plate.width / 10 + 1, plate.height),
                  cv::Scalar(150, 50, 20), cv::FILLED);
    synth_internal::DrawTextFit(
        image, "KA " + synth_internal::RandomNumberText(rng),
        cv::Rect(plate.x + plate.width / 9, plate.y, plate.width * 8 / 9, plate.height),
        cv::Scalar(15, 15, 15), rng);
  } else {  // roof
    cv::rectangle(image, cv::Rect(w * 18 / 100, 0, w * 12 / 100, h), glass, cv::FILLED);
    cv::rectangle(image, cv::Rect(w * 72 / 100, 0, w * 10 / 100, h), glass, cv::FILLED);
  }
  ModulateByNoise(image, 0.5 * ppm, 3, 0.12, rng);
  return texture;
}

cv::Vec3b CarPaint(Rng& rng) {
  static const std::array<cv::Vec3b, 8> kPaint = {
      cv::Vec3b(235, 235, 235), cv::Vec3b(180, 180, 175), cv::Vec3b(30, 30, 30),
      cv::Vec3b(40, 40, 170),   cv::Vec3b(140, 70, 20),   cv::Vec3b(90, 90, 90),
      cv::Vec3b(50, 90, 40),    cv::Vec3b(120, 170, 200)};
  return kPaint[rng.UniformInt(0, kPaint.size() - 1)];
}

}  // namespace epiloc
