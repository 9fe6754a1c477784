// The centreline of a synthetic road: a smooth chain of straights and circular arcs in the world's
// local ENU frame (x east, y north, metres), parametrised by the along-road distance s.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace epiloc {

// One piece of the centreline: a straight (curvature 0) or a circular arc.
struct CentrelinePiece {
  double s0_m = 0.0;      // along-road distance at the start of the piece
  double length_m = 0.0;  // > 0
  Eigen::Vector2d start_in_world = Eigen::Vector2d::Zero();  // (east, north), metres
  double start_yaw_rad = 0.0;    // travel direction at the start, counter-clockwise from east
  double curvature_per_m = 0.0;  // 1 / radius; positive turns left
};

// Where a horizontal point lies relative to the centreline.
struct RoadCoordinates {
  double s_m = 0.0;  // along-road distance of the foot point
  double d_m = 0.0;  // lateral offset, positive to the left of the travel direction
  int piece = 0;     // the piece the coordinates refer to
};

class Centreline {
 public:
  Centreline() = default;
  // `pieces` contiguous (each starts where the previous ends, same heading) with increasing s0.
  // Throws Error if empty, a length is not positive or the chain is not contiguous.
  explicit Centreline(std::vector<CentrelinePiece> pieces);

  const std::vector<CentrelinePiece>& pieces() const { return pieces_; }
  double start_s_m() const;
  double end_s_m() const;

  // Index of the piece holding s (the first / last piece beyond the ends).
  int PieceAt(double s_m) const;
  // Point at s and lateral offset d (positive left); beyond the ends the end pieces continue
  // (a straight continues straight, an arc continues its circle).
  Eigen::Vector2d PointAt(double s_m, double d_m = 0.0) const;
  // Travel direction at s, radians counter-clockwise from east.
  double YawAt(double s_m) const;
  // Unit travel direction and unit left normal at s.
  Eigen::Vector2d TangentAt(double s_m) const;
  Eigen::Vector2d LeftAt(double s_m) const;

  // Exact road coordinates of `point` relative to piece `piece` (its straight line or circle
  // extended), without searching other pieces.
  RoadCoordinates ToRoadOnPiece(const Eigen::Vector2d& point, int piece) const;
  // Road coordinates relative to the nearest piece.
  RoadCoordinates ToRoad(const Eigen::Vector2d& point) const;

 private:
  // Per piece: unit tangent and left normal at the start, and the circle centre of an arc.
  struct Cached {
    Eigen::Vector2d tangent, left, centre;
  };
  std::vector<CentrelinePiece> pieces_;
  std::vector<Cached> cached_;
};

}  // namespace epiloc
