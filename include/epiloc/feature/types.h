// Feature storage types shared by extraction, the database and matching.
#pragma once

#include <cstdint>

#include <Eigen/Core>

namespace epiloc {

// One row per feature: x, y (pixels; centre of the top-left pixel = (0, 0)), size (pixels, the
// diameter of the keypoint's neighbourhood, OpenCV's KeyPoint::size), orientation (radians, from
// the +x axis towards +y, i.e. clockwise as displayed; OpenCV's KeyPoint::angle in radians).
using FeatureKeypoints = Eigen::Matrix<float, Eigen::Dynamic, 4, Eigen::RowMajor>;
// One row of 128 bytes per feature (SIFT, OpenCV's uint8 descriptor).
using FeatureDescriptors = Eigen::Matrix<uint8_t, Eigen::Dynamic, 128, Eigen::RowMajor>;

// Rows of both are in the same order: decreasing detector response (strongest first), so the
// first N rows are the N strongest features.
struct FeatureSet {
  FeatureKeypoints keypoints;
  FeatureDescriptors descriptors;
  int size() const { return static_cast<int>(keypoints.rows()); }
};

}  // namespace epiloc
