// A synthetic street world with exact geometry, for tests and demos (in the spirit of COLMAP's
// SynthesizeDataset): a curved road with lanes, markings, kerbs and pavements, building fronts with
// side walls, distant buildings, poles with signs, parked cars, ground and sky. Every surface is a
// planar convex quad with its own procedural texture, so renderings and LiDAR samples can be
// computed exactly.
//
// Frame: the world's local ENU frame about `World::origin` (x east, y north, z up, metres). The
// road surface lies at z = 0. Everything is deterministic for a seed.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <optional>
#include "epiloc/geo/geodetic.h"

#include "epiloc/synth/centreline.h"
#include "epiloc/synth/side_street.h"
#include "epiloc/synth/texture.h"

namespace epiloc {

enum class SurfaceKind {
  kGround,      // grass and soil around the street, below the road (z < 0)
  kRoad,        // asphalt with markings, z = 0
  kSidewalk,    // pavement at kerb height
  kKerb,        // vertical kerb face
  kFacade,      // building front facing the road
  kWall,        // building side wall
  kBackground,  // distant building front
  kPole,        // street lamp / sign pole side
  kSign,        // sign board (front or back)
  kCar,         // face of a parked car
  // Appearance variants.
  kHedge,      // face of a hedge (vegetation)
  kTreeTrunk,  // side of a tree trunk
  kTreeCrown,  // face of a tree crown (a box of foliage)
};
const char* SurfaceKindName(SurfaceKind kind);

// A planar convex quad with a texture. A point at texture coordinates (u, v) metres lies at
// texture_origin + u * u_axis + v * v_axis; texture pixel (x, y) covers
// [x, x + 1) x [y, y + 1) * metres_per_pixel of the texture. The quad may cover only part of its
// texture (a trapezoid of a curved road); outside the texture the edge texels repeat.
struct Surface {
  SurfaceKind kind = SurfaceKind::kGround;
  std::array<Eigen::Vector3d, 4> corners_in_world;  // coplanar, convex, in order around the edge
  int texture = -1;  // index into World::textures; -1: hidden (e.g. a parked car taken away)
  Eigen::Vector3d texture_origin_in_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d u_axis = Eigen::Vector3d::UnitX();  // unit, along texture columns
  Eigen::Vector3d v_axis = Eigen::Vector3d::UnitY();  // unit, along texture rows, orthogonal to u

  // Unit normal u_axis x v_axis, and the plane offset: normal . x = PlaneOffset() on the plane.
  Eigen::Vector3d Normal() const { return u_axis.cross(v_axis); }
  double PlaneOffset() const { return Normal().dot(texture_origin_in_world); }
  // Texture coordinates (u, v) in metres of a point (projected onto the plane).
  Eigen::Vector2d TextureCoordinates(const Eigen::Vector3d& point_in_world) const;
  Eigen::Vector3d PointAt(double u_m, double v_m) const {
    return texture_origin_in_world + u_m * u_axis + v_m * v_axis;
  }
  // True if the point's projection onto the plane lies inside the quad (edges within tol_m count).
  bool Contains(const Eigen::Vector3d& point_in_world, double tol_m = 1e-9) const;
};

// A checkerboard X-corner drawn into a facade texture at a known position.
struct Marker {
  Eigen::Vector3d position_in_world = Eigen::Vector3d::Zero();
  int surface = -1;       // index into World::surfaces
  double square_m = 0.0;  // side of one checkerboard square
};

// Hedges and rows of identical, evenly spaced trees along stretches of the road: repetitive
// texture, part of the world (both drives see it).
struct VegetationOptions {
  double fraction = 0.0;           // share of the road's length with vegetation, on each side
  double stretch_length_m = 40.0;  // one stretch (a park front, an avenue)
  double tree_spacing_m = 7.0;     // trunks evenly spaced along a stretch
  double foliage_period_m = 0.5;   // hedge and crown textures repeat with this period (u and v)

  void Check() const;
};

struct WorldOptions {
  double length_m = 300.0;            // driven length of the road (s in [0, length]), metres
  uint64_t seed = 1;                  // everything random derives from it
  Geodetic origin{49.0, 8.4, 115.0};  // geodetic position of the world origin (s = 0)
  double margin_before_m = 30.0;      // road and buildings built before s = 0
  double margin_after_m = 100.0;      // ... and after s = length (what the last frames see)
  double min_straight_m = 30.0;       // straight pieces between curves, random length in [min, max]
  double max_straight_m = 80.0;
  double min_radius_m = 60.0;   // curve radius, random in [min, max] (min: the pavement's outer
  double max_radius_m = 180.0;  // edge stays 5 m from the centre of the tightest curve)
  double max_turn_deg = 55.0;   // turn of one curve, random in [15, max]
  RoadProfile road;             // lanes, parking strips, pavements, kerb
  double min_building_width_m = 8.0;  // building fronts along the road
  double max_building_width_m = 22.0;
  double min_building_height_m = 7.0;
  double max_building_height_m = 19.0;
  double max_setback_m = 2.5;         // fronts stand 3 m + [0, max] behind the kerb
  double gap_probability = 0.35;      // chance of an open gap before a building
  double max_gap_m = 9.0;             // gap width, random in [2, max]
  bool background_buildings = true;   // a second row ~30 m behind the fronts
  double pole_spacing_m = 28.0;       // street lamps / sign poles, average spacing per side
  double car_probability = 0.45;      // chance of a parked car per parking slot (6 m)
  int markers_per_facade = 2;         // checkerboard markers (exact X-corners) per building front
  double marker_square_m = 0.2;       // side of one marker square
  double facade_pixels_per_m = 48.0;  // texture resolutions
  double road_pixels_per_m = 32.0;
  double sidewalk_pixels_per_m = 24.0;
  double ground_pixels_per_m = 4.0;
  int num_threads = 2;  // texture generation threads (the result does not depend on it)

  // Appearance variants (off by default: the world is then exactly the one without them).
  VegetationOptions vegetation;
  // Side street joining from the right (issue 14's turn-in drives); built when enabled.
  SideStreetOptions side_street;

  // Throws Error naming the first invalid field.
  void Check() const;
};

// A parking slot (6 m of a parking strip) and the car parked in it.
struct ParkingSlot {
  double s_m = 0.0;        // along-road distance of the slot's centre
  int side = -1;           // -1: right of the travel direction, +1: left
  int first_surface = -1;  // the car's five surfaces start here in World::surfaces; -1: empty
};

// A stretch of road side with a hedge and a tree row.
struct VegetationStretch {
  int side = -1;  // -1: right of the travel direction, +1: left
  double s0_m = 0.0, s1_m = 0.0;
};

struct World {
  WorldOptions options;
  Centreline centreline;  // s = 0 at the world origin (ENU (0, 0))
  std::vector<Surface> surfaces;
  std::vector<Texture> textures;  // with mip levels
  std::vector<Marker> markers;
  std::vector<double> crossings_s_m;      // zebra crossings (start of the stripes)
  std::optional<SideStreet> side_street;  // when options.side_street.enabled
  // Appearance variants.
  std::vector<ParkingSlot> parking_slots;     // free slots in order of s, per side
  std::vector<VegetationStretch> vegetation;  // in order of side, then s

  const Geodetic& origin() const { return options.origin; }
  // Road-surface height at a horizontal position (0: the road is flat).
  double RoadHeight() const { return 0.0; }
  // Horizontal position at along-road distance s and lateral offset d (positive left).
  Eigen::Vector3d RoadPoint(double s_m, double d_m) const;
  // Lateral offset of the right driving lane's centre (negative: right of the centreline).
  double RightLaneCentre() const { return -0.5 * options.road.lane_width_m; }
};

// Builds the world for `options` (calls options.Check()). Takes ~2 s for 300 m on 2 threads.
World BuildWorld(const WorldOptions& options);

// Writes the options, centreline pieces, markers, parking slots, vegetation stretches and surfaces
// (kind, corners, texture size; hidden ones flagged) as JSON. Throws Error if the file cannot be
// written.
void WriteWorldJson(const World& world, const std::string& path);

}  // namespace epiloc
