// world.json: what a synthetic world is made of, for evaluation and plotting.
#include <fstream>

#include <nlohmann/json.hpp>

#include "epiloc/core/error.h"
#include "epiloc/synth/world.h"

namespace epiloc {
namespace {

using Json = nlohmann::json;

Json Vec(const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); }

}  // namespace

void WriteWorldJson(const World& world, const std::string& path) {
  const WorldOptions& o = world.options;
  Json j;
  j["frame"] = "local ENU about origin: x east, y north, z up, metres; road surface at z = 0";
  j["origin"] = {
      {"lat_deg", o.origin.lat_deg}, {"lon_deg", o.origin.lon_deg}, {"alt_m", o.origin.alt_m}};
  j["options"] = {{"length_m", o.length_m},
                  {"seed", o.seed},
                  {"margin_before_m", o.margin_before_m},
                  {"margin_after_m", o.margin_after_m},
                  {"min_straight_m", o.min_straight_m},
                  {"max_straight_m", o.max_straight_m},
                  {"min_radius_m", o.min_radius_m},
                  {"max_radius_m", o.max_radius_m},
                  {"max_turn_deg", o.max_turn_deg},
                  {"lane_width_m", o.road.lane_width_m},
                  {"parking_width_m", o.road.parking_width_m},
                  {"sidewalk_width_m", o.road.sidewalk_width_m},
                  {"kerb_height_m", o.road.kerb_height_m},
                  {"min_building_width_m", o.min_building_width_m},
                  {"max_building_width_m", o.max_building_width_m},
                  {"min_building_height_m", o.min_building_height_m},
                  {"max_building_height_m", o.max_building_height_m},
                  {"max_setback_m", o.max_setback_m},
                  {"gap_probability", o.gap_probability},
                  {"max_gap_m", o.max_gap_m},
                  {"background_buildings", o.background_buildings},
                  {"pole_spacing_m", o.pole_spacing_m},
                  {"car_probability", o.car_probability},
                  {"markers_per_facade", o.markers_per_facade},
                  {"marker_square_m", o.marker_square_m},
                  {"facade_pixels_per_m", o.facade_pixels_per_m},
                  {"road_pixels_per_m", o.road_pixels_per_m},
                  {"sidewalk_pixels_per_m", o.sidewalk_pixels_per_m},
                  {"ground_pixels_per_m", o.ground_pixels_per_m},
                  {"vegetation_fraction", o.vegetation.fraction},
                  {"vegetation_stretch_length_m", o.vegetation.stretch_length_m},
                  {"tree_spacing_m", o.vegetation.tree_spacing_m},
                  {"foliage_period_m", o.vegetation.foliage_period_m}};
  Json pieces = Json::array();
  for (const CentrelinePiece& p : world.centreline.pieces()) {
    pieces.push_back({{"s0_m", p.s0_m},
                      {"length_m", p.length_m},
                      {"start", {p.start_in_world.x(), p.start_in_world.y()}},
                      {"start_yaw_rad", p.start_yaw_rad},
                      {"curvature_per_m", p.curvature_per_m}});
  }
  j["centreline"] = pieces;
  j["right_lane_centre_d_m"] = world.RightLaneCentre();
  j["crossings_s_m"] = world.crossings_s_m;
  Json markers = Json::array();
  for (const Marker& m : world.markers) {
    markers.push_back(
        {{"position", Vec(m.position_in_world)}, {"surface", m.surface}, {"square_m", m.square_m}});
  }
  j["markers"] = markers;
  Json slots = Json::array();
  for (const ParkingSlot& p : world.parking_slots) {
    slots.push_back({{"s_m", p.s_m}, {"side", p.side}, {"first_surface", p.first_surface}});
  }
  j["parking_slots"] = slots;
  Json vegetation = Json::array();
  for (const VegetationStretch& v : world.vegetation) {
    vegetation.push_back({{"side", v.side}, {"s0_m", v.s0_m}, {"s1_m", v.s1_m}});
  }
  j["vegetation"] = vegetation;
  Json surfaces = Json::array();
  for (const Surface& s : world.surfaces) {
    Json corners = Json::array();
    for (const Eigen::Vector3d& c : s.corners_in_world) corners.push_back(Vec(c));
    Json surface = {{"kind", SurfaceKindName(s.kind)},
                    {"corners", corners},
                    {"texture_origin", Vec(s.texture_origin_in_world)},
                    {"u_axis", Vec(s.u_axis)},
                    {"v_axis", Vec(s.v_axis)}};
    if (s.texture >= 0) {
      const Texture& t = world.textures[s.texture];
      surface["texture_size_px"] = {t.image.cols, t.image.rows};
      surface["metres_per_pixel"] = t.metres_per_pixel;
    } else {
      surface["hidden"] = true;  // e.g. a parked car taken away (the query's world)
    }
    surfaces.push_back(surface);
  }
  j["surfaces"] = surfaces;
  if (world.side_street) {
    const SideStreet& side = *world.side_street;
    j["side_street"] = {{"junction_s_m", side.junction_s_m},
                        {"angle_deg", side.angle_deg},
                        {"junction", {side.junction_in_world.x(), side.junction_in_world.y()}},
                        {"away", {side.away.x(), side.away.y()}},
                        {"length_m", side.length_m}};
  }
  std::ofstream out(path);
  if (!out) Throw("{}: cannot open for writing", path);
  out << j.dump(1) << '\n';
  out.close();
  if (!out) Throw("{}: write failed", path);
}

}  // namespace epiloc
