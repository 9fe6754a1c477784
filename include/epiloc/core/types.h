// Identifier types shared by all modules, each with an invalid sentinel.
#pragma once

#include <cstdint>

namespace epiloc {

// A frame's number within its drive (KITTI frame number, video frame index, ...).
using frame_t = int64_t;
constexpr frame_t kInvalidFrame = -1;

// Row ids of the route database.
using drive_t = int64_t;
constexpr drive_t kInvalidDrive = -1;
using camera_t = int64_t;
constexpr camera_t kInvalidCamera = -1;
using image_t = int64_t;  // a database frame (one image of one drive)
constexpr image_t kInvalidImage = -1;

}  // namespace epiloc
