// Procedural textures of the synthetic street world: deterministic for a seed, rich in corners and
// blobs at several scales so that SIFT and AKAZE find many stable features.
//
// Texture coordinates: texture pixel (x, y) covers [x, x + 1) x [y, y + 1) times
// metres_per_pixel in texture coordinates (u, v) metres, so its centre lies at
// u = (x + 0.5) * metres_per_pixel. Images are BGR, CV_8UC3.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "epiloc/synth/centreline.h"

namespace epiloc {

// A texture image with its scale and mip levels for anti-aliased sampling.
struct Texture {
  cv::Mat image;                   // BGR, CV_8UC3; level 0
  double metres_per_pixel = 0.02;  // size of one texture pixel on the surface
  // Mip levels made by cv::pyrDown (level 0 = image): level l pixel x lies at level-0 pixel
  // coordinate x * 2^l. Filled by BuildPyramid().
  std::vector<cv::Mat> levels;

  double width_m() const { return image.cols * metres_per_pixel; }
  double height_m() const { return image.rows * metres_per_pixel; }
  void BuildPyramid();
};

// Small, fast, portable random generator (SplitMix64): the same numbers on every platform, so
// worlds and drives are identical for the same seed.
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  uint64_t Next();
  double Uniform();  // [0, 1)
  double Uniform(double lo, double hi);
  int UniformInt(int lo, int hi);  // [lo, hi] inclusive
  bool Bernoulli(double p);
  double Normal();  // standard normal (Box-Muller)

 private:
  uint64_t state_;
};

// A well-mixed seed for the sub-stream `salt` of `seed`.
uint64_t MixSeed(uint64_t seed, uint64_t salt);

// Smooth value noise in [0, 1] on a unit lattice, and its fractal sum (octaves of doubling
// frequency and halving amplitude), as functions of a continuous position.
double ValueNoise(double x, double y, uint64_t seed);
double FractalNoise(double x, double y, int octaves, uint64_t seed);
// Uniform hash of a lattice cell in [0, 1).
double CellHash(int64_t ix, int64_t iy, uint64_t seed);

// A CV_32F field of `size` with fractal noise in about [0, 1], coarsest cells of `cell_px` pixels.
cv::Mat NoiseField(cv::Size size, double cell_px, int octaves, Rng& rng);
// Multiplies the image by (1 - amplitude / 2 + amplitude * noise).
void ModulateByNoise(cv::Mat& image, double cell_px, int octaves, double amplitude, Rng& rng);

// A 2x2 checkerboard X-corner drawn into a texture at a texel corner.
struct MarkerPlacement {
  Eigen::Vector2d corner_uv_m;  // texture coordinates (u, v) of the X-corner, metres
  double square_m = 0.0;        // side of one square
};

// A building front of `width_m` x `height_m` (v = 0 at the top): wall material, window grid with
// frames, a ground floor with shop windows, door and a sign with text, posters, dirt. Adds
// `num_markers` checkerboard markers at eye level and reports them.
Texture FacadeTexture(double width_m,
                      double height_m,
                      double pixels_per_m,
                      int num_markers,
                      double marker_square_m,
                      uint64_t seed,
                      std::vector<MarkerPlacement>* markers);
// A building side wall (plaster or brick, a few windows).
Texture WallTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed);
// A distant building front (coarse window grid).
Texture BackgroundTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed);
// A traffic or shop sign with glyph-like shapes and text.
Texture SignTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed);
// Metal (pole, back of a sign).
Texture MetalTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed);
// One face of a parked car; `face` 0 = side, 1 = front, 2 = back, 3 = roof. `body_bgr` is the
// paint colour shared by the car's faces.
Texture CarTexture(int face,
                   double width_m,
                   double height_m,
                   double pixels_per_m,
                   const cv::Vec3b& body_bgr,
                   uint64_t seed);
// A car paint colour of a palette of common ones.
cv::Vec3b CarPaint(Rng& rng);
// Foliage (hedges, tree crowns) or bark: a random pattern of `period_px` x `period_px` texels
// repeated over `size` texels, so texel (x, y) equals texel (x + period_px, y) and
// (x, y + period_px) (`bark`: vertical streaks of brown instead of leaves).
Texture VegetationTexture(cv::Size size,
                          int period_px,
                          double metres_per_pixel,
                          bool bark,
                          const cv::Vec3b& base_bgr,
                          uint64_t seed);

// Painted road symbol (text, arrow, manhole cover, crack, patch) placed in road coordinates:
// the stamp image's top row lies at s1 and its left column at d1 (as a driver reads it).
struct RoadStamp {
  double s0_m = 0.0, s1_m = 0.0;  // along-road extent
  double d0_m = 0.0, d1_m = 0.0;  // lateral extent (d0 < d1)
  cv::Mat alpha;                  // CV_8U coverage
  cv::Vec3b bgr;                  // colour where alpha = 255
};

// Cross-section of the road, lateral offsets in metres from the centreline.
struct RoadProfile {
  double lane_width_m = 3.5;      // one driving lane each way
  double parking_width_m = 2.2;   // parking strip outside each driving lane
  double sidewalk_width_m = 7.5;  // from the kerb to the outer edge of the pavement
  double kerb_height_m = 0.12;
  double asphalt_half_width_m() const { return lane_width_m + parking_width_m; }
};

// What a textured patch of the ground plane is, and where: the texel (x, y) centre lies at
// world (east, north) = origin + (x + 0.5) * mpp * u_axis + (y + 0.5) * mpp * v_axis.
struct GroundPatch {
  Eigen::Vector2d origin_in_world;
  Eigen::Vector2d u_axis;
  Eigen::Vector2d v_axis;
  int piece = -1;  // centreline piece for road coordinates (road, sidewalk, kerb)
};

// Texture functions evaluated per texel from world and road coordinates, so that markings, paving
// and noise continue seamlessly across neighbouring surfaces. `stamps` sorted by s0.
Texture RoadTexture(cv::Size size,
                    double metres_per_pixel,
                    const GroundPatch& patch,
                    const Centreline& centreline,
                    const RoadProfile& profile,
                    const std::vector<RoadStamp>& stamps,
                    const std::vector<double>& crossings_s_m,
                    uint64_t seed);
Texture SidewalkTexture(cv::Size size,
                        double metres_per_pixel,
                        const GroundPatch& patch,
                        const Centreline& centreline,
                        const RoadProfile& profile,
                        uint64_t seed);
Texture GroundTexture(cv::Size size,
                      double metres_per_pixel,
                      const GroundPatch& patch,
                      uint64_t seed);
// Vertical kerb face; u runs along the road.
Texture KerbTexture(double width_m, double height_m, double pixels_per_m, uint64_t seed);
// Random road stamps along [s_begin, s_end] (lane texts and arrows, manholes, patches, cracks).
std::vector<RoadStamp> MakeRoadStamps(double s_begin_m,
                                      double s_end_m,
                                      const RoadProfile& profile,
                                      uint64_t seed);

}  // namespace epiloc
