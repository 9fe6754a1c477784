#include "epiloc/synth/centreline.h"

#include <cmath>
#include <limits>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

// Below this curvature a piece is treated as straight (radius > 1000 km).
constexpr double kStraightCurvature = 1e-9;

bool IsStraight(const CentrelinePiece& piece) {
  return std::abs(piece.curvature_per_m) < kStraightCurvature;
}

Eigen::Vector2d PieceEnd(const CentrelinePiece& piece, double local_s, double* yaw) {
  const double k = piece.curvature_per_m;
  const double yaw0 = piece.start_yaw_rad;
  if (IsStraight(piece)) {
    *yaw = yaw0;
    return piece.start_in_world + local_s * Eigen::Vector2d(std::cos(yaw0), std::sin(yaw0));
  }
  *yaw = yaw0 + k * local_s;
  return piece.start_in_world +
         Eigen::Vector2d(std::sin(*yaw) - std::sin(yaw0), -std::cos(*yaw) + std::cos(yaw0)) / k;
}

}  // namespace

Centreline::Centreline(std::vector<CentrelinePiece> pieces) : pieces_(std::move(pieces)) {
  EPILOC_CHECK(!pieces_.empty(), "centreline: no pieces");
  for (size_t i = 0; i < pieces_.size(); ++i) {
    const CentrelinePiece& p = pieces_[i];
    Cached c;
    c.tangent = Eigen::Vector2d(std::cos(p.start_yaw_rad), std::sin(p.start_yaw_rad));
    c.left = Eigen::Vector2d(-c.tangent.y(), c.tangent.x());
    c.centre = IsStraight(p) ? p.start_in_world : p.start_in_world + c.left / p.curvature_per_m;
    cached_.push_back(c);
    EPILOC_CHECK(p.length_m > 0 && std::isfinite(p.length_m),
                 "centreline: piece {} has length {} m", i, p.length_m);
    if (i == 0) continue;
    const CentrelinePiece& prev = pieces_[i - 1];
    double yaw = 0;
    const Eigen::Vector2d end = PieceEnd(prev, prev.length_m, &yaw);
    EPILOC_CHECK(std::abs(prev.s0_m + prev.length_m - p.s0_m) < 1e-6 &&
                     (end - p.start_in_world).norm() < 1e-6 &&
                     std::abs(std::remainder(yaw - p.start_yaw_rad, 2 * M_PI)) < 1e-9,
                 "centreline: piece {} does not continue piece {}", i, i - 1);
  }
}

double Centreline::start_s_m() const { return pieces_.front().s0_m; }

double Centreline::end_s_m() const { return pieces_.back().s0_m + pieces_.back().length_m; }

int Centreline::PieceAt(double s_m) const {
  int lo = 0, hi = static_cast<int>(pieces_.size()) - 1;
  while (lo < hi) {
    const int mid = (lo + hi + 1) / 2;
    if (pieces_[mid].s0_m <= s_m) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  return lo;
}

Eigen::Vector2d Centreline::PointAt(double s_m, double d_m) const {
  const CentrelinePiece& piece = pieces_[PieceAt(s_m)];
  double yaw = 0;
  const Eigen::Vector2d p = PieceEnd(piece, s_m - piece.s0_m, &yaw);
  return p + d_m * Eigen::Vector2d(-std::sin(yaw), std::cos(yaw));
}

double Centreline::YawAt(double s_m) const {
  const CentrelinePiece& piece = pieces_[PieceAt(s_m)];
  if (IsStraight(piece)) return piece.start_yaw_rad;
  return piece.start_yaw_rad + piece.curvature_per_m * (s_m - piece.s0_m);
}

Eigen::Vector2d Centreline::TangentAt(double s_m) const {
  const double yaw = YawAt(s_m);
  return Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
}

Eigen::Vector2d Centreline::LeftAt(double s_m) const {
  const double yaw = YawAt(s_m);
  return Eigen::Vector2d(-std::sin(yaw), std::cos(yaw));
}

RoadCoordinates Centreline::ToRoadOnPiece(const Eigen::Vector2d& point, int piece_index) const {
  const CentrelinePiece& piece = pieces_.at(piece_index);
  RoadCoordinates rc;
  rc.piece = piece_index;
  const Eigen::Vector2d& tangent = cached_[piece_index].tangent;
  const Eigen::Vector2d& left = cached_[piece_index].left;
  if (IsStraight(piece)) {
    const Eigen::Vector2d v = point - piece.start_in_world;
    rc.s_m = piece.s0_m + v.dot(tangent);
    rc.d_m = v.dot(left);
    return rc;
  }
  const double k = piece.curvature_per_m;
  const Eigen::Vector2d& centre = cached_[piece_index].centre;
  const Eigen::Vector2d v0 = piece.start_in_world - centre;
  const Eigen::Vector2d v = point - centre;
  const double angle = std::atan2(v0.x() * v.y() - v0.y() * v.x(), v0.dot(v));
  rc.s_m = piece.s0_m + angle / k;
  rc.d_m = 1.0 / k - (k > 0 ? 1.0 : -1.0) * v.norm();
  return rc;
}

RoadCoordinates Centreline::ToRoad(const Eigen::Vector2d& point) const {
  RoadCoordinates best;
  double best_distance = std::numeric_limits<double>::infinity();
  for (int i = 0; i < static_cast<int>(pieces_.size()); ++i) {
    RoadCoordinates rc = ToRoadOnPiece(point, i);
    const CentrelinePiece& piece = pieces_[i];
    double distance = std::abs(rc.d_m);
    const bool first = i == 0, last = i + 1 == static_cast<int>(pieces_.size());
    if ((rc.s_m < piece.s0_m && !first) || (rc.s_m > piece.s0_m + piece.length_m && !last)) {
      const double s_end = rc.s_m < piece.s0_m ? piece.s0_m : piece.s0_m + piece.length_m;
      distance = (PointAt(s_end) - point).norm();
    }
    if (distance < best_distance) {
      best_distance = distance;
      best = rc;
    }
  }
  return best;
}

}  // namespace epiloc
