// A drive directory that another program is still writing (a recorder in the vehicle): drive.json
// (calibration, file names) is read once; rows appended to its frames CSV and to its GNSS file
// (position CSV or NMEA log) are read as they appear. The frames must come from a CSV of image
// files; a row is taken only once its line is complete, so a recorder writes the image file first
// and then appends the row.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "epiloc/io/drive.h"

namespace epiloc {

class DriveFollower {
 public:
  // Reads `dir`/drive.json. Throws Error as LoadDrive does for a malformed manifest, and if its
  // frames do not come from a "csv" or its GNSS format is kitti_oxts (neither can grow).
  explicit DriveFollower(const std::string& dir);
  ~DriveFollower();
  DriveFollower(const DriveFollower&) = delete;
  DriveFollower& operator=(const DriveFollower&) = delete;

  // The manifest: dir, name, camera, colour, max_gap_s (frames and GNSS are not kept here).
  const Drive& manifest() const;
  // Whether drive.json names a GNSS file.
  bool has_gnss() const;

  // The frames appended to the frames CSV since the last call (complete rows, in file order; the
  // checks of LoadDrive: unique numbers, times never decreasing, image files exist). Empty while
  // the CSV does not exist yet.
  std::vector<FrameRecord> PollFrames();
  // Reads the GNSS rows appended since the last call, then the position at `timestamp_s` from
  // the samples read so far (PositionTrack::Interpolate with the manifest's max_gap_s: between
  // samples, or extrapolated past the last one by at most max_gap_s), or none. Calls must come
  // in non-decreasing time: older samples are dropped, so memory stays bounded.
  std::optional<PositionSample> GnssAt(double timestamp_s);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace epiloc
