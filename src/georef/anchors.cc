#include "epiloc/georef/anchors.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Standard normal numbers by Box-Muller from mt19937_64, identical on every platform (unlike
// std::normal_distribution).
class Gaussian {
 public:
  explicit Gaussian(uint64_t seed) : engine_(seed) {}
  double operator()() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = (static_cast<double>(engine_() >> 11) + 1.0) * 0x1.0p-53;
    const double u2 = static_cast<double>(engine_() >> 11) * 0x1.0p-53;
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * M_PI * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * M_PI * u2);
  }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

// The number in extra column `at` of `row`: nullopt where the column is missing or empty, or
// its text is not a finite number.
std::optional<double> OptionalNumber(const ResultRow& row, size_t at) {
  if (at >= row.extra.size() || row.extra[at].empty()) return std::nullopt;
  char* end = nullptr;
  const double value = std::strtod(row.extra[at].c_str(), &end);
  if (!end || *end != '\0' || !std::isfinite(value)) return std::nullopt;
  return value;
}

}  // namespace

AnchorSet ReadAnchors(const std::string& path, const std::string& method) {
  const ResultTable table = ReadResultCsv(path);
  AnchorSet set;
  set.path = path;
  const auto scale_column =
      std::find(table.extra_columns.begin(), table.extra_columns.end(), "scale_m_per_unit");
  const size_t scale_at = static_cast<size_t>(scale_column - table.extra_columns.begin());
  const auto drift_column =
      std::find(table.extra_columns.begin(), table.extra_columns.end(), "scale_drift_per_m");
  const size_t drift_at = static_cast<size_t>(drift_column - table.extra_columns.begin());
  bool any = false;
  for (const ResultRow& row : table.rows) {
    if (row.method != method) continue;
    any = true;
    if (row.status != ResultStatus::kOk) {
      ++set.rows_not_ok;
      continue;
    }
    Anchor anchor;
    anchor.frame = row.frame;
    anchor.timestamp_s = row.timestamp_s;
    anchor.position = row.position;
    anchor.enu_from_cam = row.enu_from_cam;
    // A scale that does not parse or is not positive is no scale, a drift that does not parse
    // or is not finite no drift (the other columns decide whether the row is an anchor).
    if (const std::optional<double> scale = OptionalNumber(row, scale_at); scale && *scale > 0.0) {
      anchor.scale_m_per_unit = scale;
    }
    anchor.scale_drift_per_m = OptionalNumber(row, drift_at);
    anchor.line = row.line;
    set.anchors.push_back(anchor);
  }
  if (!any) {
    Throw("{}: no rows of method '{}' (methods present: {})", path, method,
          fmt::join(table.Methods(), ", "));
  }
  std::stable_sort(set.anchors.begin(), set.anchors.end(),
                   [](const Anchor& a, const Anchor& b) { return a.timestamp_s < b.timestamp_s; });
  for (size_t i = 1; i < set.anchors.size(); ++i) {
    if (set.anchors[i].timestamp_s == set.anchors[i - 1].timestamp_s) {
      Throw("{}: two anchors at time {}", Where(path, set.anchors[i].line),
            FormatDouble(set.anchors[i].timestamp_s));
    }
  }
  return set;
}

void AnchorSimulationOptions::Check() const {
  EPILOC_CHECK(step >= 1, "--anchor-step must be >= 1, got {}", step);
  EPILOC_CHECK(first >= 0, "--anchor-first must be >= 0, got {}", first);
  EPILOC_CHECK(std::isfinite(position_sigma_m) && position_sigma_m >= 0.0,
               "--anchor-noise-m must be >= 0, got {}", position_sigma_m);
  EPILOC_CHECK(std::isfinite(rotation_sigma_deg) && rotation_sigma_deg >= 0.0,
               "--anchor-noise-deg must be >= 0, got {}", rotation_sigma_deg);
}

ResultTable SimulateAnchors(const Drive& drive, const AnchorSimulationOptions& options) {
  options.Check();
  if (!drive.ground_truth || drive.ground_truth->samples.empty()) {
    Throw("{}: the drive has no ground truth to simulate anchors from", drive.dir);
  }
  ResultTable table;
  table.path = drive.dir;
  Gaussian gaussian(options.seed);
  const FramePositions positions = PositionFrames(drive, *drive.ground_truth);
  for (size_t i = static_cast<size_t>(options.first); i < drive.frames.size();
       i += static_cast<size_t>(options.step)) {
    const auto& truth = positions.per_frame[i];
    if (!truth || !truth->enu_from_cam) continue;
    const EnuFrame local(truth->position);
    const Eigen::Vector3d error(gaussian(), gaussian(), gaussian());
    const Eigen::Vector3d rotation_error = Eigen::Vector3d(gaussian(), gaussian(), gaussian()) *
                                           options.rotation_sigma_deg * M_PI / 180.0;
    ResultRow row;
    row.frame = drive.frames[i].frame;
    row.timestamp_s = drive.frames[i].timestamp_s;
    row.method = "anchor";
    row.status = ResultStatus::kOk;
    row.position = local.ToGeodetic(options.position_sigma_m * error);
    row.has_position = true;
    Eigen::Quaterniond q = *truth->enu_from_cam;
    if (rotation_error.norm() > 0.0) {
      q = q *
          Eigen::Quaterniond(Eigen::AngleAxisd(rotation_error.norm(), rotation_error.normalized()));
    }
    row.enu_from_cam = q.normalized();
    table.rows.push_back(row);
  }
  if (table.rows.empty()) {
    Throw("{}: no frame has a ground-truth pose with orientation to simulate anchors from",
          drive.dir);
  }
  return table;
}

}  // namespace epiloc
