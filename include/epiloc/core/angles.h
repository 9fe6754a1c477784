// Degrees and radians: the conversion factors the modules share (options and reports are in
// degrees, Eigen and OpenCV take radians).
#pragma once

#include <cmath>

namespace epiloc {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRadToDeg = 180.0 / M_PI;

}  // namespace epiloc
