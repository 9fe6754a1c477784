// Query cameras for synthetic drives: presets (a 1080p wide-angle dashcam, a VGA camera) and
// helpers to set a camera's size and field of view.
#pragma once

#include <string>
#include <vector>

#include "epiloc/camera/camera.h"

namespace epiloc {

struct DriveOptions;

// Horizontal field of view, degrees: the angle between the rays through the left and right image
// edges (x = -0.5 and width - 0.5) on the principal point's row, distortion included.
double HorizontalFovDeg(const Camera& camera);
// `camera` with fx = fy chosen so that HorizontalFovDeg() is `hfov_deg` (distortion kept).
// Throws Error if hfov_deg is not in (1, 179) or the distortion cannot reach it.
Camera WithHorizontalFovDeg(const Camera& camera, double hfov_deg);
// `camera` resized to width x height pixels, principal point in the centre, focal lengths scaled
// by the ratio of the widths (the same horizontal field of view for a pinhole camera).
Camera WithSize(const Camera& camera, int width, int height);
// Throws Error (prefixed with `where`) unless the radial distortion grows monotonically out to
// the image corners and inverts there, so that every pixel sees exactly one ray.
void CheckDistortionInvertible(const Camera& camera, const std::string& where);

// Query camera presets: "default" (DriveOptions::Query(): 640x360, fx 500, 15 Hz), "dashcam1080"
// (1920x1080 at 30 Hz, 120 deg horizontal field of view, wide-angle barrel distortion), "vga"
// (640x480 at 15 Hz, 60 deg, mild barrel distortion).
std::vector<std::string> QueryCameraPresets();
// Sets the camera and frame rate of `drive` to the preset's. Throws Error for an unknown name.
void ApplyQueryCameraPreset(const std::string& name, DriveOptions* drive);

}  // namespace epiloc
