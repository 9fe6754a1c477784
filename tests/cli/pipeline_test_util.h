// Helpers of the survey-chain tests.
#pragma once

#include "epiloc/anchor/anchor.h"
#include "epiloc/georef/anchors.h"

namespace epiloc {

// The ok frames of an anchoring run as georeferencing anchors (what `epiloc georef` reads from
// the anchor CSV).
inline AnchorSet OkAnchors(const AnchorDriveResult& anchored) {
  AnchorSet anchors;
  anchors.path = "anchors";
  for (const AnchorResult& a : anchored.frames) {
    if (a.status == AnchorStatus::kOk) {
      anchors.anchors.push_back({a.frame, a.timestamp_s, a.position, a.enu_from_cam, 0});
    }
  }
  return anchors;
}

}  // namespace epiloc
