// Cameras shared by the camera module's tests.
#pragma once

#include "epiloc/camera/camera.h"

namespace epiloc {

// KITTI-like camera (raw, unrectified) with strong barrel distortion.
inline Camera KittiCamera() {
  Camera camera;
  camera.width = 1392;
  camera.height = 512;
  camera.fx = 984.0;
  camera.fy = 981.0;
  camera.cx = 690.0;
  camera.cy = 233.2;
  camera.distortion = {-0.37, 0.2, 0.002, 0.001, -0.07};
  return camera;
}

}  // namespace epiloc
