#include "epiloc/synth/texture.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "draw_util.h"
#include "epiloc/core/error.h"

namespace epiloc {

using synth_internal::Jitter;
using synth_internal::Px;
using synth_internal::ToScalar;

void Texture::BuildPyramid() {
  EPILOC_CHECK(!image.empty() && image.type() == CV_8UC3, "texture: image must be CV_8UC3");
  levels.clear();
  levels.push_back(image);
  while (levels.back().cols > 2 && levels.back().rows > 2 && levels.size() < 12) {
    cv::Mat next;
    cv::pyrDown(levels.back(), next);
    levels.push_back(next);
  }
}

uint64_t Rng::Next() {
  uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double Rng::Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }

double Rng::Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }

int Rng::UniformInt(int lo, int hi) {
  if (hi <= lo) return lo;
  return lo + static_cast<int>(Next() % static_cast<uint64_t>(hi - lo + 1));
}

bool Rng::Bernoulli(double p) { return Uniform() < p; }

double Rng::Normal() {
  const double u1 = std::max(Uniform(), 1e-300);
  const double u2 = Uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

uint64_t MixSeed(uint64_t seed, uint64_t salt) {
  Rng rng(seed ^ (salt * 0xD1B54A32D192ED03ULL + 0x2545F4914F6CDD1DULL));
  rng.Next();
  return rng.Next();
}

double CellHash(int64_t ix, int64_t iy, uint64_t seed) {
  // A cheap 32-bit avalanche hash: texture noise needs speed more than statistical quality.
  uint32_t h = static_cast<uint32_t>(seed) ^ static_cast<uint32_t>(seed >> 32);
  h ^= static_cast<uint32_t>(ix) * 0x27D4EB2Du;
  h = (h ^ (h >> 15)) * 0x2C1B3C6Du;
  h ^= static_cast<uint32_t>(iy) * 0x165667B1u;
  h = (h ^ (h >> 12)) * 0x297A2D39u;
  h ^= h >> 15;
  return h * (1.0 / 4294967296.0);
}

double ValueNoise(double x, double y, uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int64_t ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3 - 2 * tx);
  ty = ty * ty * (3 - 2 * ty);
  const double a = CellHash(ix, iy, seed), b = CellHash(ix + 1, iy, seed);
  const double c = CellHash(ix, iy + 1, seed), d = CellHash(ix + 1, iy + 1, seed);
  return (a + (b - a) * tx) * (1 - ty) + (c + (d - c) * tx) * ty;
}

double FractalNoise(double x, double y, int octaves, uint64_t seed) {
  double sum = 0, norm = 0, amplitude = 1, frequency = 1;
  for (int o = 0; o < octaves; ++o) {
    sum += amplitude * ValueNoise(x * frequency, y * frequency, seed + 1013 * o);
    norm += amplitude;
    amplitude *= 0.5;
    frequency *= 2.0;
  }
  return sum / norm;
}

cv::Mat NoiseField(cv::Size size, double cell_px, int octaves, Rng& rng) {
  cv::Mat sum(size, CV_32F, cv::Scalar(0));
  double norm = 0, amplitude = 1;
  for (int o = 0; o < octaves && cell_px >= 1.0; ++o, cell_px *= 0.5, amplitude *= 0.5) {
    const int gw = static_cast<int>(std::ceil(size.width / cell_px)) + 3;
    const int gh = static_cast<int>(std::ceil(size.height / cell_px)) + 3;
    cv::Mat grid(gh, gw, CV_32F);
    for (int i = 0; i < grid.rows; ++i) {
      for (int j = 0; j < grid.cols; ++j) grid.at<float>(i, j) = static_cast<float>(rng.Uniform());
    }
    cv::Mat up;
    const cv::Size up_size(static_cast<int>(std::lround(gw * cell_px)),
                           static_cast<int>(std::lround(gh * cell_px)));
    cv::resize(grid, up, up_size, 0, 0, cell_px > 1.5 ? cv::INTER_CUBIC : cv::INTER_NEAREST);
    const int ox = std::min(up.cols - size.width, static_cast<int>(cell_px));
    const int oy = std::min(up.rows - size.height, static_cast<int>(cell_px));
    cv::scaleAdd(up(cv::Rect(ox, oy, size.width, size.height)), amplitude, sum, sum);
    norm += amplitude;
  }
  if (norm > 0) sum /= norm;
  return sum;
}

void ModulateByNoise(cv::Mat& image, double cell_px, int octaves, double amplitude, Rng& rng) {
  const cv::Mat noise = NoiseField(image.size(), cell_px, octaves, rng);
  for (int y = 0; y < image.rows; ++y) {
    cv::Vec3b* row = image.ptr<cv::Vec3b>(y);
    const float* n = noise.ptr<float>(y);
    for (int x = 0; x < image.cols; ++x) {
      const double f = 1.0 - amplitude / 2 + amplitude * n[x];
      for (int c = 0; c < 3; ++c) row[x][c] = cv::saturate_cast<uchar>(row[x][c] * f);
    }
  }
}

namespace {

void FillRect(cv::Mat& image, const cv::Rect& rect, const cv::Scalar& colour) {
  cv::rectangle(image, rect, colour, cv::FILLED);
}

void DrawBricks(cv::Mat& image, const cv::Vec3b& brick, double pixels_per_m, Rng& rng) {
  const cv::Vec3b mortar = Jitter(cv::Vec3b(170, 180, 185), 0.1, rng);
  image.setTo(ToScalar(mortar));
  const int course = std::max(3, Px(0.08, pixels_per_m));
  const int length = std::max(6, Px(0.25, pixels_per_m));
  for (int y = 0, row = 0; y < image.rows; y += course, ++row) {
    for (int x = (row % 2) ? -length / 2 : 0; x < image.cols; x += length) {
      const cv::Vec3b c = Jitter(brick, 0.14, rng);
      FillRect(image, cv::Rect(x, y, length - 1, course - 1), ToScalar(c));
    }
  }
}

void DrawPanels(cv::Mat& image, const cv::Vec3b& base, double pixels_per_m, Rng& rng) {
  const int pw = Px(rng.Uniform(1.2, 2.4), pixels_per_m);
  const int ph = Px(rng.Uniform(0.8, 1.6), pixels_per_m);
  for (int y = 0; y < image.rows; y += ph) {
    for (int x = 0; x < image.cols; x += pw) {
      FillRect(image, cv::Rect(x, y, pw, ph), ToScalar(Jitter(base, 0.08, rng)));
      cv::rectangle(image, cv::Rect(x, y, pw, ph), ToScalar(Jitter(base, 0.1, rng) * 0.6), 1);
    }
  }
}

struct WindowStyle {
  cv::Vec3b frame;
  cv::Vec3b glass;
  int mullions = 0;  // 0 none, 1 vertical bar, 2 cross, 3 grid
  bool shutters = false;
  cv::Vec3b shutter;
};

void DrawWindow(cv::Mat& image, const cv::Rect& r, const WindowStyle& style, double ppm, Rng& rng) {
  const int t = std::max(1, Px(0.07, ppm));
  // Sill below and lintel above, wider than the opening.
  FillRect(image, cv::Rect(r.x - t, r.y + r.height, r.width + 2 * t, std::max(1, t)),
           ToScalar(Jitter(cv::Vec3b(200, 205, 210), 0.08, rng)));
  if (rng.Bernoulli(0.5)) {
    FillRect(image, cv::Rect(r.x - t / 2, r.y - t, r.width + t, t), cv::Scalar(120, 125, 130));
  }
  FillRect(image, r, ToScalar(style.frame));
  const cv::Rect glass(r.x + t, r.y + t, r.width - 2 * t, r.height - 2 * t);
  if (glass.width < 2 || glass.height < 2) return;
  const cv::Vec3b g = Jitter(style.glass, 0.25, rng);
  FillRect(image, glass, ToScalar(g));
  // Sky reflection: a lighter slanted band.
  const int x0 = glass.x + rng.UniformInt(0, glass.width), w = glass.width / 3 + 1;
  const cv::Point band[4] = {{x0, glass.y},
                             {x0 + w, glass.y},
                             {x0 + w - glass.height / 2, glass.y + glass.height},
                             {x0 - glass.height / 2, glass.y + glass.height}};
  cv::Mat roi = image(glass);
  cv::Mat reflection = roi.clone();
  std::vector<cv::Point> shifted;
  for (const cv::Point& p : band) shifted.push_back(p - glass.tl());
  cv::fillConvexPoly(reflection, shifted, ToScalar(Jitter(cv::Vec3b(190, 170, 150), 0.15, rng)));
  cv::addWeighted(roi, 0.6, reflection, 0.4, 0, roi);
  // Curtains or blinds behind the glass.
  const double what = rng.Uniform();
  if (what < 0.35) {
    const int cw = static_cast<int>(glass.width * rng.Uniform(0.25, 0.5));
    const cv::Scalar curtain = ToScalar(synth_internal::BrightColour(rng) * 0.8);
    FillRect(image, cv::Rect(glass.x, glass.y, cw, glass.height), curtain);
    if (rng.Bernoulli(0.5)) {
      FillRect(image, cv::Rect(glass.x + glass.width - cw, glass.y, cw, glass.height), curtain);
    }
  } else if (what < 0.55) {
    const int down = static_cast<int>(glass.height * rng.Uniform(0.2, 0.8));
    const cv::Scalar blind = ToScalar(Jitter(cv::Vec3b(200, 210, 215), 0.1, rng));
    FillRect(image, cv::Rect(glass.x, glass.y, glass.width, down), blind);
    for (int y = glass.y + 2; y < glass.y + down; y += 3) {
      cv::line(image, {glass.x, y}, {glass.x + glass.width - 1, y}, blind * 0.8);
    }
  }
  const cv::Scalar bar = ToScalar(style.frame);
  const int cx = glass.x + glass.width / 2, cy = glass.y + glass.height * 2 / 5;
  if (style.mullions >= 1) FillRect(image, cv::Rect(cx - t / 2, glass.y, t, glass.height), bar);
  if (style.mullions >= 2) FillRect(image, cv::Rect(glass.x, cy - t / 2, glass.width, t), bar);
  if (style.mullions >= 3) {
    FillRect(image, cv::Rect(glass.x, glass.y + glass.height * 3 / 4, glass.width, t), bar);
  }
  if (style.shutters) {
    for (const int sx : {r.x - r.width / 2 - t, r.x + r.width + t}) {
      const cv::Rect s(sx, r.y, r.width / 2, r.height);
      FillRect(image, s, ToScalar(style.shutter));
      for (int y = s.y + 2; y < s.y + s.height; y += 3) {
        cv::line(image, {s.x, y}, {s.x + s.width - 1, y}, ToScalar(style.shutter * 0.7));
      }
    }
  }
}

void DrawShopWindow(cv::Mat& image, const cv::Rect& r, double ppm, Rng& rng) {
  const int t = std::max(1, Px(0.08, ppm));
  FillRect(image, r, ToScalar(Jitter(cv::Vec3b(60, 60, 60), 0.3, rng)));
  const cv::Rect glass(r.x + t, r.y + t, r.width - 2 * t, r.height - 2 * t);
  if (glass.width < 4 || glass.height < 4) return;
  FillRect(image, glass, ToScalar(Jitter(cv::Vec3b(70, 60, 50), 0.3, rng)));
  // Goods on display: shelves of boxes and round things.
  const int num_items = rng.UniformInt(4, 12);
  for (int i = 0; i < num_items; ++i) {
    const int w = std::max(2, static_cast<int>(glass.width * rng.Uniform(0.05, 0.2)));
    const int h = std::max(2, static_cast<int>(glass.height * rng.Uniform(0.05, 0.25)));
    const int x = glass.x + rng.UniformInt(0, std::max(0, glass.width - w));
    const int y =
        glass.y + glass.height / 3 + rng.UniformInt(0, std::max(0, glass.height * 2 / 3 - h));
    const cv::Scalar c = ToScalar(synth_internal::BrightColour(rng));
    if (rng.Bernoulli(0.6)) {
      FillRect(image, cv::Rect(x, y, w, h), c);
    } else {
      cv::circle(image, {x + w / 2, y + h / 2}, std::min(w, h) / 2, c, cv::FILLED, cv::LINE_AA);
    }
  }
  if (rng.Bernoulli(0.6)) {
    synth_internal::DrawTextFit(image, synth_internal::RandomWord(rng),
                                cv::Rect(glass.x, glass.y + 2, glass.width, glass.height / 5),
                                ToScalar(synth_internal::BrightColour(rng)), rng);
  }
}

void DrawGroundFloor(cv::Mat& image, double width_m, double ground_floor_m, double ppm, Rng& rng) {
  const int rows = image.rows;
  const auto v_of = [&](double z) { return rows - Px(z, ppm); };
  // Sign band across the shop front.
  const cv::Rect band(Px(0.3, ppm), v_of(ground_floor_m - 0.25), Px(width_m - 0.6, ppm),
                      Px(0.7, ppm));
  const cv::Vec3b band_colour = synth_internal::BrightColour(rng);
  FillRect(image, band, ToScalar(band_colour));
  cv::rectangle(image, band, ToScalar(band_colour * 0.5), std::max(1, Px(0.04, ppm)));
  const int logo = band.height;
  synth_internal::DrawGlyph(image, cv::Rect(band.x + logo / 4, band.y, logo, logo),
                            ToScalar(Jitter(cv::Vec3b(255, 255, 255) - band_colour, 0.2, rng)),
                            rng);
  const cv::Rect text_box(band.x + logo * 3 / 2, band.y + band.height / 8,
                          std::min(band.width - logo * 2, Px(rng.Uniform(3, 9), ppm)),
                          band.height * 3 / 4);
  std::string text = synth_internal::RandomWord(rng);
  if (rng.Bernoulli(0.4)) text += " " + synth_internal::RandomWord(rng);
  const cv::Scalar text_colour = band_colour[0] + band_colour[1] + band_colour[2] > 380
                                     ? cv::Scalar(25, 25, 25)
                                     : cv::Scalar(245, 245, 245);
  synth_internal::DrawTextFit(image, text, text_box, text_colour, rng);
  // Shop windows and doors between pillars.
  double u = rng.Uniform(0.3, 0.8);
  while (u < width_m - 1.2) {
    const bool door = rng.Bernoulli(0.3);
    const double w = std::min(width_m - 0.4 - u, door ? 1.1 : rng.Uniform(1.6, 3.4));
    if (w < 0.9) break;
    if (door) {
      const cv::Rect d(Px(u, ppm), v_of(2.2), Px(w, ppm), Px(2.2, ppm));
      FillRect(image, d, ToScalar(Jitter(cv::Vec3b(40, 60, 90), 0.4, rng)));
      cv::rectangle(image, d, cv::Scalar(30, 30, 30), std::max(1, Px(0.05, ppm)));
      cv::circle(image, {d.x + d.width * 4 / 5, d.y + d.height / 2}, std::max(1, Px(0.04, ppm)),
                 cv::Scalar(180, 190, 200), cv::FILLED);
      synth_internal::DrawTextFit(image, synth_internal::RandomNumberText(rng),
                                  cv::Rect(d.x, d.y - Px(0.3, ppm), d.width, Px(0.25, ppm)),
                                  cv::Scalar(240, 240, 240), rng);
    } else {
      DrawShopWindow(image,
                     cv::Rect(Px(u, ppm), v_of(ground_floor_m - 1.1), Px(w, ppm),
                              Px(ground_floor_m - 1.6, ppm)),
                     ppm, rng);
    }
    u += w + rng.Uniform(0.4, 0.9);
  }
}

}  // namespace

Texture FacadeTexture(double width_m,
                      double height_m,
                      double pixels_per_m,
                      int num_markers,
                      double marker_square_m,
                      uint64_t seed,
                      std::vector<MarkerPlacement>* markers) {
  Rng rng(seed);
  const double ppm = pixels_per_m;
  Texture texture;
  texture.metres_per_pixel = 1.0 / ppm;
  cv::Mat& image = texture.image;
  image.create(Px(height_m, ppm), Px(width_m, ppm), CV_8UC3);
  const cv::Vec3b wall = synth_internal::WallColour(rng);
  const int material = rng.UniformInt(0, 2);
  if (material == 0) {
    DrawBricks(image, Jitter(cv::Vec3b(60, 80, 150), 0.25, rng), ppm, rng);
  } else if (material == 1) {
    image.setTo(ToScalar(wall));
    ModulateByNoise(image, 0.6 * ppm, 4, 0.2, rng);
  } else {
    DrawPanels(image, wall, ppm, rng);
  }
  const auto v_of = [&](double z) { return image.rows - Px(z, ppm); };
  const double ground_floor = rng.Uniform(3.4, 4.4);
  const double floor_h = rng.Uniform(2.9, 3.4);
  const int num_floors = std::max(0, static_cast<int>((height_m - ground_floor - 0.6) / floor_h));
  const double spacing = rng.Uniform(1.9, 2.8);
  const int num_columns = std::max(1, static_cast<int>((width_m - 0.8) / spacing));
  const double margin = (width_m - num_columns * spacing) / 2;
  const double ww = rng.Uniform(0.9, std::min(1.5, spacing - 0.6));
  const double wh = rng.Uniform(1.3, std::min(1.8, floor_h - 1.0));
  WindowStyle style;
  style.frame = rng.Bernoulli(0.6) ? Jitter(cv::Vec3b(235, 235, 235), 0.05, rng)
                                   : Jitter(cv::Vec3b(40, 70, 100), 0.3, rng);
  style.glass = Jitter(cv::Vec3b(90, 70, 55), 0.3, rng);
  style.mullions = rng.UniformInt(0, 3);
  style.shutters = rng.Bernoulli(0.25) && spacing - ww > ww * 0.9;
  style.shutter = Jitter(cv::Vec3b(60, 110, 60), 0.4, rng);
  const bool string_courses = rng.Bernoulli(0.5);
  for (int f = 0; f < num_floors; ++f) {
    const double z_floor = ground_floor + f * floor_h;
    if (string_courses) {
      FillRect(image, cv::Rect(0, v_of(z_floor + 0.1), image.cols, Px(0.15, ppm)),
               ToScalar(Jitter(wall, 0.2, rng) * 0.8));
    }
    for (int c = 0; c < num_columns; ++c) {
      const double u0 = margin + c * spacing + (spacing - ww) / 2;
      DrawWindow(image, cv::Rect(Px(u0, ppm), v_of(z_floor + 0.9 + wh), Px(ww, ppm), Px(wh, ppm)),
                 style, ppm, rng);
    }
  }
  DrawGroundFloor(image, width_m, ground_floor, ppm, rng);
  // Cornice at the top.
  const int cornice = Px(0.35, ppm);
  FillRect(image, cv::Rect(0, 0, image.cols, cornice), ToScalar(Jitter(wall, 0.2, rng) * 0.75));
  const int dentil = std::max(2, Px(0.12, ppm));
  for (int x = 0; x < image.cols; x += 2 * dentil) {
    FillRect(image, cv::Rect(x, cornice, dentil, dentil), ToScalar(Jitter(wall, 0.2, rng) * 0.85));
  }
  // Posters and graffiti at street level.
  for (int i = rng.UniformInt(0, 2); i > 0; --i) {
    const cv::Rect poster(Px(rng.Uniform(0.2, std::max(0.3, width_m - 1.0)), ppm), v_of(2.0),
                          Px(0.6, ppm), Px(0.85, ppm));
    synth_internal::DrawPoster(image, poster, rng);
  }
  if (rng.Bernoulli(0.4)) {
    std::vector<cv::Point> stroke;
    cv::Point p(Px(rng.Uniform(0, width_m), ppm), v_of(rng.Uniform(0.4, 1.4)));
    for (int i = 0; i < 12; ++i) {
      stroke.push_back(p);
      p += cv::Point(rng.UniformInt(-Px(0.3, ppm), Px(0.3, ppm)),
                     rng.UniformInt(-Px(0.2, ppm), Px(0.2, ppm)));
    }
    cv::polylines(image, stroke, false, ToScalar(synth_internal::BrightColour(rng)),
                  std::max(1, Px(0.05, ppm)), cv::LINE_AA);
  }
  ModulateByNoise(image, 2.5 * ppm, 4, 0.2, rng);
  // Checkerboard markers with a white margin, X-corner exactly on a texel corner.
  const int n = std::max(4, Px(marker_square_m, ppm));
  std::vector<cv::Point> placed;
  for (int m = 0, attempts = 0; m < num_markers && attempts < 200; ++attempts) {
    const cv::Point corner(Px(rng.Uniform(0.8, width_m - 0.8), ppm), v_of(rng.Uniform(1.3, 2.6)));
    bool clear = corner.x - 2 * n >= 0 && corner.x + 2 * n <= image.cols && corner.y - 2 * n >= 0;
    for (const cv::Point& q : placed) clear = clear && cv::norm(q - corner) > 5 * n;
    if (!clear) continue;
    placed.push_back(corner);
    FillRect(image, cv::Rect(corner.x - 3 * n / 2, corner.y - 3 * n / 2, 3 * n, 3 * n),
             cv::Scalar(235, 235, 235));
    FillRect(image, cv::Rect(corner.x - n, corner.y - n, n, n), cv::Scalar(20, 20, 20));
    FillRect(image, cv::Rect(corner.x, corner.y, n, n), cv::Scalar(20, 20, 20));
    if (markers) {
      markers->push_back({Eigen::Vector2d(corner.x, corner.y) / ppm, n / ppm});
    }
    ++m;
  }
  return texture;
}

Texture WallTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed) {
  Rng rng(seed);
  const double ppm = pixels_per_m;
  Texture texture;
  texture.metres_per_pixel = 1.0 / ppm;
  texture.image.create(Px(height_m, ppm), Px(width_m, ppm), CV_8UC3);
  cv::Mat& image = texture.image;
  if (rng.Bernoulli(0.4)) {
    DrawBricks(image, Jitter(cv::Vec3b(70, 90, 140), 0.25, rng), ppm, rng);
  } else {
    image.setTo(ToScalar(synth_internal::WallColour(rng)));
    ModulateByNoise(image, 0.8 * ppm, 4, 0.25, rng);
  }
  WindowStyle style;
  style.frame = Jitter(cv::Vec3b(220, 220, 220), 0.1, rng);
  style.glass = Jitter(cv::Vec3b(90, 75, 60), 0.3, rng);
  style.mullions = rng.UniformInt(0, 2);
  const double floor_h = rng.Uniform(2.9, 3.4);
  for (double z = 1.0; z + 1.5 < height_m; z += floor_h) {
    for (double u = rng.Uniform(1.0, 3.0); u + 1.2 < width_m; u += rng.Uniform(2.5, 6.0)) {
      if (rng.Bernoulli(0.5)) {
        DrawWindow(image,
                   cv::Rect(Px(u, ppm), image.rows - Px(z + 1.4, ppm), Px(0.9, ppm), Px(1.3, ppm)),
                   style, ppm, rng);
      }
    }
  }
  if (rng.Bernoulli(0.5)) {
    synth_internal::DrawPoster(image,
                               cv::Rect(Px(rng.Uniform(0.5, std::max(0.6, width_m - 2)), ppm),
                                        image.rows - Px(2.4, ppm), Px(1.2, ppm), Px(1.6, ppm)),
                               rng);
  }
  ModulateByNoise(image, 3.0 * ppm, 4, 0.25, rng);
  return texture;
}

Texture BackgroundTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed) {
  Rng rng(seed);
  const double ppm = pixels_per_m;
  Texture texture;
  texture.metres_per_pixel = 1.0 / ppm;
  texture.image.create(Px(height_m, ppm), Px(width_m, ppm), CV_8UC3);
  cv::Mat& image = texture.image;
  const cv::Vec3b wall = synth_internal::WallColour(rng);
  image.setTo(ToScalar(wall));
  ModulateByNoise(image, 2.0 * ppm, 3, 0.25, rng);
  const double spacing = rng.Uniform(1.8, 3.0), floor_h = rng.Uniform(2.8, 3.4);
  const cv::Vec3b glass = Jitter(cv::Vec3b(100, 80, 60), 0.3, rng);
  for (double z = 1.0; z + 2.0 < height_m; z += floor_h) {
    for (double u = 0.6; u + 1.2 < width_m; u += spacing) {
      const cv::Rect r(Px(u, ppm), image.rows - Px(z + 1.6, ppm), Px(1.1, ppm), Px(1.5, ppm));
      FillRect(image, r, ToScalar(Jitter(glass, rng.Bernoulli(0.15) ? 0.9 : 0.2, rng)));
    }
  }
  FillRect(image, cv::Rect(0, 0, image.cols, Px(0.5, ppm)), ToScalar(wall * 0.7));
  return texture;
}

}  // namespace epiloc
