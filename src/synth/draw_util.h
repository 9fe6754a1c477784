// Drawing helpers shared by the texture generators of the synth module (not installed).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "epiloc/synth/texture.h"

namespace epiloc {
namespace synth_internal {

// Metres to pixels at `pixels_per_m`, rounded.
inline int Px(double metres, double pixels_per_m) {
  return static_cast<int>(std::lround(metres * pixels_per_m));
}

// A colour varied by +-amount (relative) in brightness and a little in hue.
cv::Vec3b Jitter(const cv::Vec3b& bgr, double amount, Rng& rng);
cv::Scalar ToScalar(const cv::Vec3b& bgr);
// A random colour of a palette of wall / paint / sign colours.
cv::Vec3b WallColour(Rng& rng);
cv::Vec3b BrightColour(Rng& rng);
// A random word for shop signs and posters, a random plate / number text.
std::string RandomWord(Rng& rng);
std::string RandomNumberText(Rng& rng);
// Draws `text` centred in `box`, scaled to fit (cv::putText, anti-aliased, random Hershey font).
void DrawTextFit(cv::Mat& image,
                 const std::string& text,
                 const cv::Rect& box,
                 const cv::Scalar& colour,
                 Rng& rng);
// Random glyph-like shape (polygon, star, ring, arrow) filling about `box`.
void DrawGlyph(cv::Mat& image, const cv::Rect& box, const cv::Scalar& colour, Rng& rng);
// A poster: coloured background, glyphs and a line or two of text.
void DrawPoster(cv::Mat& image, const cv::Rect& box, Rng& rng);

}  // namespace synth_internal
}  // namespace epiloc
