#include "epiloc/synth/moving_objects.h"

#include <cmath>
#include <filesystem>
#include <set>

#include <gtest/gtest.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/synth/appearance.h"
#include "epiloc/synth/render.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// A nearly straight street (5 km radii): the camera's optical axis runs along the lane, so the
// depth of the lead vehicle's back at the image centre is its gap.
const World& StraightWorld() {
  static const World world = [] {
    WorldOptions o;
    o.length_m = 60;
    o.margin_after_m = 40;
    o.seed = 4;
    o.min_radius_m = o.max_radius_m = 5000;
    return BuildWorld(o);
  }();
  return world;
}

DriveOptions QueryOptions() {
  DriveOptions query = DriveOptions::Query();
  query.lateral_offset_m = 0.3;  // behind the lead car, a little to its left
  return query;
}

TEST(MovingObjects, LeadVehicleIsAheadAtTheGapInBothDrives) {
  const World& world = StraightWorld();
  const auto shared = std::make_shared<const World>(world);
  const DrivePath survey(world, DriveOptions::Survey(), world.options.length_m, 1);
  const DrivePath query(world, QueryOptions(), world.options.length_m, 2);
  AppearanceOptions options;
  options.moving.lead_vehicle_gap_m = 12;
  const std::array<DriveScene, 2> scenes = MakeDriveScenes(options, shared, survey, query, 7);
  ASSERT_TRUE(scenes[0].objects && scenes[1].objects);
  // The same car, textures and all, in both drives.
  const std::vector<Texture>& a = scenes[0].objects->textures();
  const std::vector<Texture>& b = scenes[1].objects->textures();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i)
    EXPECT_EQ(cv::norm(a[i].image, b[i].image, cv::NORM_INF), 0);

  const int back_face = static_cast<int>(world.surfaces.size()) + 3;  // side, side, front, back
  std::vector<double> gaps[2];
  for (int d = 0; d < 2; ++d) {
    const DrivePath& path = d == 0 ? survey : query;
    const DriveOptions drive = d == 0 ? DriveOptions::Survey() : QueryOptions();
    RenderOptions render;
    render.depth = true;
    render.surface_ids = true;
    const Renderer renderer(drive.camera, render);
    double max_error = 0;
    int frames = 0;
    for (double s = 5; s < world.options.length_m - 10; s += 12) {
      const double t = path.TimeAtS(s);
      const std::vector<MovingObjectState> states = scenes[d].objects->StatesAt(t);
      ASSERT_EQ(states.size(), 1u);
      const MovingObjectState& lead = states[0];
      EXPECT_EQ(lead.kind, "lead");
      gaps[d].push_back(lead.gap_m);
      EXPECT_NEAR(lead.s_m - 0.5 * lead.length_m - path.SAt(t), lead.gap_m, 1e-9);
      const RenderResult r = scenes[d].Render(renderer, t, path.CamFromWorld(t));
      // The lead car's back is seen where the camera projects its centre, at the depth of the gap
      // (the optical axis runs along the straight road; the car is lower than the camera, so the
      // image centre sees over its roof).
      const Eigen::Vector3d back_centre =
          lead.world_from_body *
          Eigen::Vector3d(-0.5 * lead.length_m, 0, 0.03 + 0.5 * lead.height_m);
      const Eigen::Vector2d p = drive.camera.Project(path.CamFromWorld(t) * back_centre);
      const int px = static_cast<int>(std::lround(p.x())),
                py = static_cast<int>(std::lround(p.y()));
      ASSERT_TRUE(px >= 0 && py >= 0 && px < drive.camera.width && py < drive.camera.height);
      EXPECT_LT(std::abs(px - drive.camera.cx), 0.15 * drive.camera.width);
      EXPECT_EQ(r.surface_id.at<int>(py, px), back_face) << "drive " << d << " s " << s;
      const double depth = r.depth.at<float>(py, px);
      max_error = std::max(max_error, std::abs(depth - lead.gap_m));
      ++frames;
    }
    std::printf("drive %d: %d frames, gap %.2f-%.2f m, max |depth of its back - gap| %.3f m\n", d,
                frames, *std::min_element(gaps[d].begin(), gaps[d].end()),
                *std::max_element(gaps[d].begin(), gaps[d].end()), max_error);
    EXPECT_LT(max_error, 0.03);
  }
  // The gap varies slowly within the stated range, and differently in the two drives.
  double differ = 0;
  for (int d = 0; d < 2; ++d) {
    for (const double g : gaps[d]) {
      EXPECT_GE(g, 12 * (1 - options.moving.lead_gap_variation) - 1e-9);
      EXPECT_LE(g, 12 * (1 + options.moving.lead_gap_variation) + 1e-9);
    }
  }
  for (double s = 5; s < 50; s += 1) {
    const double gs = scenes[0].objects->StatesAt(survey.TimeAtS(s))[0].gap_m;
    const double gq = scenes[1].objects->StatesAt(query.TimeAtS(s))[0].gap_m;
    differ = std::max(differ, std::abs(gs - gq));
  }
  EXPECT_GT(differ, 0.5);
  EXPECT_GT(*std::max_element(gaps[0].begin(), gaps[0].end()) -
                *std::min_element(gaps[0].begin(), gaps[0].end()),
            0.3);
}

TEST(MovingObjects, TrafficPassesWithoutCollisionsAndDiffersPerDrive) {
  const World& world = StraightWorld();
  const auto shared = std::make_shared<const World>(world);
  const DrivePath survey(world, DriveOptions::Survey(), world.options.length_m, 1);
  const DrivePath query(world, QueryOptions(), world.options.length_m, 2);
  AppearanceOptions options;
  options.moving.lead_vehicle_gap_m = 10;
  options.moving.traffic = 6;
  const std::array<DriveScene, 2> scenes = MakeDriveScenes(options, shared, survey, query, 7);
  for (int d = 0; d < 2; ++d) {
    const DrivePath& path = d == 0 ? survey : query;
    const DriveObjects& objects = *scenes[d].objects;
    EXPECT_EQ(objects.num_objects(), 7);
    std::set<int> seen, passed;
    for (double t = path.start_time_s(); t <= path.end_time_s(); t += 0.05) {
      const std::vector<MovingObjectState> states = objects.StatesAt(t);
      const Eigen::Vector3d camera = path.CamFromWorld(t).Inverse().translation;
      for (size_t i = 0; i < states.size(); ++i) {
        seen.insert(states[i].object);
        const Eigen::Vector3d c = states[i].world_from_body.translation;
        // Never where the camera's car is (a box of 2.5 m x 1.2 m around the camera at most).
        const RoadCoordinates rc = world.centreline.ToRoad(c.head<2>());
        const RoadCoordinates cam = world.centreline.ToRoad(camera.head<2>());
        const bool same_lane = std::abs(rc.d_m - cam.d_m) < 0.5 * states[i].width_m + 1.0;
        if (same_lane) {
          EXPECT_GT(rc.s_m - 0.5 * states[i].length_m - cam.s_m, 2.5) << states[i].kind;
        }
        if (states[i].kind == "oncoming" && std::abs(rc.s_m - cam.s_m) < 0.6) {
          passed.insert(states[i].object);
        }
        for (size_t j = i + 1; j < states.size(); ++j) {
          const MovingObjectState& o = states[j];
          const RoadCoordinates rj =
              world.centreline.ToRoad(o.world_from_body.translation.head<2>());
          if (std::abs(rj.d_m - rc.d_m) > 0.5 * (o.width_m + states[i].width_m)) continue;
          EXPECT_GT(std::abs(rj.s_m - rc.s_m), 0.5 * (o.length_m + states[i].length_m))
              << states[i].kind << " and " << o.kind << " overlap at t " << t;
        }
      }
    }
    std::printf("drive %d: %zu of %d cars seen on the road, %zu oncoming passed the camera\n", d,
                seen.size(), objects.num_objects(), passed.size());
    EXPECT_EQ(static_cast<int>(seen.size()), objects.num_objects());
    EXPECT_GE(passed.size(), 2u);
  }
  // The traffic differs between the drives; the lead vehicle does not.
  const std::vector<Texture>& a = scenes[0].objects->textures();
  const std::vector<Texture>& b = scenes[1].objects->textures();
  ASSERT_EQ(a.size(), b.size());
  int same = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    same += a[i].image.size() == b[i].image.size() &&
            cv::norm(a[i].image, b[i].image, cv::NORM_INF) == 0;
  }
  EXPECT_EQ(same, 5);  // the lead vehicle's five faces
}

TEST(MovingObjects, CsvHoldsTheExactPoses) {
  const World& world = StraightWorld();
  const DrivePath survey(world, DriveOptions::Survey(), world.options.length_m, 1);
  MovingObjectOptions options;
  options.lead_vehicle_gap_m = 15;
  options.traffic = 3;
  const DriveObjects objects(world, survey, options, MakeCarModel(3), 11);
  const fs::path file = fs::temp_directory_path() / "epiloc_synth_moving_objects.csv";
  const std::vector<double> times = survey.FrameTimes();
  objects.WriteCsv(file.string(), times);
  CsvReader csv(file.string());
  int rows = 0;
  while (csv.Next()) {
    const int frame = static_cast<int>(csv.GetInt("frame"));
    const std::vector<MovingObjectState> states = objects.StatesAt(times[frame]);
    const int object = static_cast<int>(csv.GetInt("object"));
    const auto it = std::find_if(states.begin(), states.end(),
                                 [&](const MovingObjectState& s) { return s.object == object; });
    ASSERT_NE(it, states.end());
    EXPECT_EQ(csv.Get("kind"), it->kind);
    const Eigen::Vector3d x(csv.GetDouble("x_m"), csv.GetDouble("y_m"), csv.GetDouble("z_m"));
    EXPECT_EQ((x - it->world_from_body.translation).norm(), 0.0);
    const Eigen::Vector3d forward = it->world_from_body.rotation * Eigen::Vector3d::UnitX();
    EXPECT_NEAR(csv.GetDouble("yaw_rad"), std::atan2(forward.y(), forward.x()), 1e-15);
    if (it->kind == "lead") {
      EXPECT_EQ(csv.GetDouble("gap_m"), it->gap_m);
    } else {
      EXPECT_FALSE(csv.GetOptionalDouble("gap_m").has_value());
    }
    ++rows;
  }
  EXPECT_GT(rows, static_cast<int>(times.size()));
  fs::remove(file);
}

TEST(ParkedCars, SlotsHoldTheWorldsParkedCars) {
  const World& world = StraightWorld();
  int occupied = 0, cars = 0;
  for (const Surface& s : world.surfaces) cars += s.kind == SurfaceKind::kCar;
  for (size_t i = 0; i < world.parking_slots.size(); ++i) {
    const ParkingSlot& slot = world.parking_slots[i];
    if (i > 0 && world.parking_slots[i - 1].side == slot.side) {
      EXPECT_GE(slot.s_m - world.parking_slots[i - 1].s_m, 6.0 - 1e-9);
    }
    if (slot.first_surface < 0) continue;
    ++occupied;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int k = 0; k < 5; ++k) {
      const Surface& s = world.surfaces[slot.first_surface + k];
      EXPECT_EQ(s.kind, SurfaceKind::kCar);
      for (const Eigen::Vector3d& c : s.corners_in_world) centre += c / 20.0;
    }
    // The car stands in its slot: within 0.5 m along the road, on the slot's parking strip.
    const RoadCoordinates rc = world.centreline.ToRoad(centre.head<2>());
    EXPECT_NEAR(rc.s_m, slot.s_m, 0.5 + 1e-6);
    const RoadProfile& road = world.options.road;
    EXPECT_NEAR(rc.d_m, slot.side * (road.lane_width_m + 0.5 * road.parking_width_m), 0.2);
  }
  EXPECT_EQ(cars, 5 * occupied);
  EXPECT_GT(occupied, 5);
}

TEST(ParkedCars, QueryWorldDiffersOnlyByTheChangedCars) {
  const World& world = StraightWorld();
  std::vector<ParkedCarChange> changes;
  const World changed = ChangeParkedCars(world, 0.3, 5, &changes);
  const int slots = static_cast<int>(world.parking_slots.size());
  ASSERT_GT(slots, 20);
  EXPECT_EQ(static_cast<int>(changes.size()), static_cast<int>(std::lround(0.3 * slots)));
  int removed = 0, added = 0, replaced = 0;
  std::set<int> hidden_expected;
  for (const ParkedCarChange& c : changes) {
    const ParkingSlot& before = world.parking_slots[c.slot];
    const ParkingSlot& after = changed.parking_slots[c.slot];
    if (c.change == "removed") {
      ++removed;
      EXPECT_LT(after.first_surface, 0);
    } else if (c.change == "added") {
      ++added;
      EXPECT_LT(before.first_surface, 0);
    } else {
      ASSERT_EQ(c.change, "replaced");
      ++replaced;
    }
    if (before.first_surface >= 0) {
      for (int k = 0; k < 5; ++k) hidden_expected.insert(before.first_surface + k);
    }
    if (c.change != "removed") {
      ASSERT_GE(after.first_surface, static_cast<int>(world.surfaces.size()));
      EXPECT_EQ(changed.surfaces[after.first_surface].kind, SurfaceKind::kCar);
    }
  }
  std::printf("%d slots: %d removed, %d added, %d replaced\n", slots, removed, added, replaced);
  EXPECT_GT(removed + replaced, 0);
  EXPECT_GT(added, 0);
  // Every surface of the survey's world is there unchanged but the changed slots' cars, hidden.
  ASSERT_EQ(changed.surfaces.size(), world.surfaces.size() + 5 * (added + replaced));
  for (size_t i = 0; i < world.surfaces.size(); ++i) {
    const Surface& s = world.surfaces[i];
    const Surface& t = changed.surfaces[i];
    for (int k = 0; k < 4; ++k) EXPECT_EQ(s.corners_in_world[k], t.corners_in_world[k]);
    EXPECT_EQ(s.kind, t.kind);
    if (hidden_expected.count(static_cast<int>(i))) {
      EXPECT_EQ(s.kind, SurfaceKind::kCar);
      EXPECT_EQ(t.texture, -1);
    } else {
      EXPECT_EQ(s.texture, t.texture);
    }
  }
  EXPECT_EQ(changed.markers.size(), world.markers.size());
  // Renderings differ only where changed cars are seen: the ids of unchanged surfaces stay.
  const DrivePath survey(world, DriveOptions::Survey(), world.options.length_m, 1);
  RenderOptions options;
  options.surface_ids = true;
  const Renderer renderer(DriveOptions::Survey().camera, options);
  int differing = 0, total = 0;
  for (double s = 5; s < 55; s += 16) {
    const Rigid3d pose = survey.CamFromWorld(survey.TimeAtS(s));
    const cv::Mat a = renderer.Render(world, pose).surface_id;
    const cv::Mat b = renderer.Render(changed, pose).surface_id;
    for (int y = 0; y < a.rows; ++y) {
      for (int x = 0; x < a.cols; ++x) {
        const int ia = a.at<int>(y, x), ib = b.at<int>(y, x);
        ++total;
        if (ia == ib) continue;
        ++differing;
        const bool a_changed = ia >= 0 && hidden_expected.count(ia);
        const bool b_new = ib >= static_cast<int>(world.surfaces.size());
        EXPECT_TRUE(a_changed || b_new) << "pixel " << x << "," << y << ": " << ia << " -> " << ib;
      }
    }
  }
  std::printf("%d of %d pixels see another surface\n", differing, total);
  EXPECT_GT(differing, 0);
  EXPECT_THROW(ChangeParkedCars(world, 1.5, 1), Error);
}

TEST(MovingObjects, OptionsAreChecked) {
  MovingObjectOptions o;
  o.lead_vehicle_gap_m = 2;
  EXPECT_THROW(o.Check(), Error);
  o = MovingObjectOptions();
  o.lead_gap_variation = 0.8;
  EXPECT_THROW(o.Check(), Error);
  AppearanceOptions a;
  a.query_parked_cars_changed = -0.1;
  EXPECT_THROW(a.Check(), Error);
}

}  // namespace
}  // namespace epiloc
