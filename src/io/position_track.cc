#include <algorithm>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/error.h"
#include "epiloc/io/drive.h"
#include "io_internal.h"

namespace epiloc {
namespace {

bool SameQuaternion(const std::optional<Eigen::Quaterniond>& a,
                    const std::optional<Eigen::Quaterniond>& b) {
  if (a.has_value() != b.has_value()) return false;
  return !a || a->coeffs() == b->coeffs();
}

bool SameGeodetic(const Geodetic& a, const Geodetic& b) {
  return a.lat_deg == b.lat_deg && a.lon_deg == b.lon_deg && a.alt_m == b.alt_m;
}

// Position (and orientation) at parameter w along a -> b (w outside [0, 1] extrapolates).
PositionSample Blend(const PositionSample& a, const PositionSample& b, double w, double t) {
  const EnuFrame frame(a.position);
  PositionSample result;
  result.timestamp_s = t;
  result.position = frame.ToGeodetic(w * frame.ToEnu(b.position));
  if (a.enu_from_cam && b.enu_from_cam) {
    // Both orientations in the ENU axes at a, then into the axes at the result's position.
    const Eigen::Quaterniond b_in_a = EnuToEnuRotation(a.position, b.position) * *b.enu_from_cam;
    const Eigen::Quaterniond q = a.enu_from_cam->slerp(w, b_in_a).normalized();
    result.enu_from_cam = (EnuToEnuRotation(result.position, a.position) * q).normalized();
  }
  return result;
}

}  // namespace

bool FrameRecord::operator==(const FrameRecord& o) const {
  return frame == o.frame && timestamp_s == o.timestamp_s && image == o.image;
}

bool PositionSample::operator==(const PositionSample& o) const {
  return timestamp_s == o.timestamp_s && SameGeodetic(position, o.position) &&
         SameQuaternion(enu_from_cam, o.enu_from_cam) && frame == o.frame;
}

bool LidarScan::operator==(const LidarScan& o) const {
  return scan == o.scan && timestamp_s == o.timestamp_s && path == o.path && format == o.format &&
         SameGeodetic(sensor_position, o.sensor_position) &&
         enu_from_sensor.coeffs() == o.enu_from_sensor.coeffs();
}

std::string Drive::ImagePath(const FrameRecord& frame) const {
  return ResolvePath(dir, frame.image);
}

std::string Drive::FrameWhere(const FrameRecord& frame) const {
  if (frames_csv.empty() || frame.line <= 0) return "";
  return Where(frames_csv, frame.line);
}

std::string Drive::VideoPath() const { return ResolvePath(dir, video); }

std::string Drive::ScanPath(const LidarScan& scan) const { return ResolvePath(dir, scan.path); }

std::optional<PositionSample> PositionTrack::Interpolate(double t, double max_gap_s) const {
  if (samples.empty()) return std::nullopt;
  const auto after =
      std::upper_bound(samples.begin(), samples.end(), t,
                       [](double time, const PositionSample& s) { return time < s.timestamp_s; });
  const size_t i = static_cast<size_t>(after - samples.begin());  // first sample later than t
  if (i > 0 && samples[i - 1].timestamp_s == t) return samples[i - 1];
  if (samples.size() == 1) {
    if (std::abs(samples[0].timestamp_s - t) > max_gap_s) return std::nullopt;
    PositionSample only = samples[0];
    only.timestamp_s = t;
    only.frame = kInvalidFrame;
    return only;
  }
  size_t a = 0;
  if (i == 0) {
    if (samples[0].timestamp_s - t > max_gap_s) return std::nullopt;
    a = 0;
  } else if (i == samples.size()) {
    if (t - samples.back().timestamp_s > max_gap_s) return std::nullopt;
    a = samples.size() - 2;
  } else {
    if (t - samples[i - 1].timestamp_s > max_gap_s || samples[i].timestamp_s - t > max_gap_s) {
      return std::nullopt;
    }
    a = i - 1;
  }
  const PositionSample& sa = samples[a];
  const PositionSample& sb = samples[a + 1];
  const double w = (t - sa.timestamp_s) / (sb.timestamp_s - sa.timestamp_s);
  return Blend(sa, sb, w, t);
}

FramePositions PositionFrames(const Drive& drive, const PositionTrack& track) {
  FramePositions result;
  result.per_frame.reserve(drive.frames.size());
  for (const auto& frame : drive.frames) {
    auto sample = track.Interpolate(frame.timestamp_s, drive.max_gap_s);
    if (sample) {
      sample->frame = frame.frame;
    } else {
      result.missing.push_back(frame.frame);
    }
    result.per_frame.push_back(std::move(sample));
  }
  if (!result.missing.empty()) {
    constexpr size_t kShown = 10;
    const size_t shown = std::min(kShown, result.missing.size());
    const std::vector<frame_t> first(result.missing.begin(), result.missing.begin() + shown);
    spdlog::warn("{}: {} of {} frames have no position within {} s of {}: frames {}{}", drive.name,
                 result.missing.size(), drive.frames.size(), drive.max_gap_s,
                 track.source.empty() ? "the track" : track.source, fmt::join(first, ", "),
                 result.missing.size() > shown ? ", ..." : "");
  }
  return result;
}

}  // namespace epiloc
