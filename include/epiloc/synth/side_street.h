// A side street joining the synthetic street from the right, for drives that come along it and
// turn into the street (the turn-in query variant). Built after the street: what stands in its
// way (buildings, parked cars, poles, the street's pavement) is removed, then its asphalt,
// pavements, kerbs and a few buildings are added.
//
// Junction frame: x along the street's travel direction at the junction, y to its left; the side
// street's axis runs through the junction point on the centreline and leaves the street towards
// the right, so that a car coming along it towards the street and turning right into the street's
// travel direction turns by `angle_deg`.
#pragma once

#include <array>

#include <Eigen/Core>

#include "epiloc/synth/centreline.h"

namespace epiloc {

struct World;

struct SideStreetOptions {
  bool enabled = false;
  double at_m = 20.0;       // wanted junction (centreline distance); the nearest feasible is taken
  double angle_deg = 90.0;  // heading change of a car turning right from it into the street
  double length_m = 60.0;   // from the street's asphalt edge along the side street's axis
  double building_probability = 0.8;  // chance of a building on each plot along it

  // Throws Error naming the first invalid field (angle in [60, 120] deg, length >= 40 m).
  void Check() const;
};

// The side street as built.
struct SideStreet {
  double junction_s_m = 0.0;  // centreline distance where its axis meets the centreline
  double angle_deg = 90.0;
  Eigen::Vector2d junction_in_world = Eigen::Vector2d::Zero();
  Eigen::Vector2d away = Eigen::Vector2d::UnitX();  // unit direction of its axis, from the street
  double length_m = 0.0;                            // from the street's asphalt edge
  double end_r_m = 0.0;   // distance of its far end from the junction point along its axis
  Centreline centreline;  // its axis, travelled towards the street (s = 0 beyond the far end)
  // The street is straight over [straight_from_s_m, straight_to_s_m] around the junction.
  double straight_from_s_m = 0.0, straight_to_s_m = 0.0;

  // True if `point` lies on asphalt at least `margin_m` from any kerb: on the street's roadway or
  // on the side street's.
  bool OnAsphalt(const World& world, const Eigen::Vector2d& point, double margin_m) const;
};

// Builds the side street of world->options.side_street into `world` and sets world->side_street.
// The junction is placed where the street is straight long enough for the mouth and a turn of up
// to 12 m radius, nearest to the wanted `at_m`. Deterministic for the world's seed. Throws Error if
// no straight stretch of the street is long enough.
void AddSideStreet(World* world);

}  // namespace epiloc
