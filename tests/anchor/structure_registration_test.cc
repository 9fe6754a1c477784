#include "epiloc/anchor/structure_registration.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "test_util.h"

namespace epiloc {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// A street of surfaces: the road (z = 0), two facades (y = +-7) with recessed windows, boxes
// (parked cars) and poles, sampled every `step_m`. The windows and boxes give surfaces facing
// along the street (x), without which the registration would slide along it.
struct Street {
  std::vector<Eigen::Vector3d> points;
  void AddRect(const Eigen::Vector3d& corner,
               const Eigen::Vector3d& u,
               const Eigen::Vector3d& v,
               double step_m) {
    const int nu = std::max(1, static_cast<int>(u.norm() / step_m));
    const int nv = std::max(1, static_cast<int>(v.norm() / step_m));
    for (int i = 0; i <= nu; ++i) {
      for (int j = 0; j <= nv; ++j) {
        points.push_back(corner + u * (static_cast<double>(i) / nu) +
                         v * (static_cast<double>(j) / nv));
      }
    }
  }
  void AddBox(const Eigen::Vector3d& min, const Eigen::Vector3d& size, double step_m) {
    const Eigen::Vector3d x(size.x(), 0, 0), y(0, size.y(), 0), z(0, 0, size.z());
    AddRect(min, x, z, step_m);
    AddRect(min + y, x, z, step_m);
    AddRect(min, y, z, step_m);
    AddRect(min + x, y, z, step_m);
    AddRect(min + z, x, y, step_m);
  }
};

Street MakeStreet(double step_m, bool with_parked_car_at_10) {
  Street s;
  s.AddRect({-20, -7, 0}, {40, 0, 0}, {0, 14, 0}, step_m);  // road
  for (const double side : {-7.0, 7.0}) {
    const double out = side > 0 ? 0.4 : -0.4;  // windows recessed into the facade
    // Irregular spacing: a strictly periodic facade would repeat along the street.
    for (double x = -20; x < 20; x += 5.0 + 2.0 * std::fmod(std::abs(x + side) * 0.37, 1.0)) {
      s.AddRect({x, side, 0}, {1.5, 0, 0}, {0, 0, 6}, step_m);              // wall
      s.AddRect({x + 1.5, side + out, 1}, {2.0, 0, 0}, {0, 0, 3}, step_m);  // window
      s.AddRect({x + 1.5, side, 1}, {0, out, 0}, {0, 0, 3}, step_m);        // its reveals
      s.AddRect({x + 3.5, side, 1}, {0, out, 0}, {0, 0, 3}, step_m);
      s.AddRect({x + 3.5, side, 0}, {1.5, 0, 0}, {0, 0, 6}, step_m);
      s.AddRect({x + 1.5, side, 0}, {2.0, 0, 0}, {0, 0, 1}, step_m);
      s.AddRect({x + 1.5, side, 4}, {2.0, 0, 0}, {0, 0, 2}, step_m);
    }
  }
  s.AddBox({-12, 4, 0}, {4.2, 1.8, 1.5}, step_m);
  s.AddBox({3, -5.5, 0}, {4.5, 1.8, 1.4}, step_m);
  if (with_parked_car_at_10) s.AddBox({10, 4.2, 0}, {4.0, 1.8, 1.5}, step_m);
  for (double x = -15; x < 20; x += 9.0) s.AddBox({x, -6.0, 0}, {0.2, 0.2, 4.0}, step_m);
  return s;
}

PointCloud ToCloud(const std::vector<Eigen::Vector3d>& points) {
  PointCloud cloud;
  for (const Eigen::Vector3d& p : points) cloud.positions.push_back(p.cast<float>());
  return cloud;
}

Similarity3 MakeSimilarity(double scale,
                           double yaw_deg,
                           double pitch_deg,
                           const Eigen::Vector3d& t) {
  Similarity3 s;
  s.scale = scale;
  s.rotation = Eigen::AngleAxisd(yaw_deg * kDegToRad, Eigen::Vector3d::UnitZ()) *
               Eigen::AngleAxisd(pitch_deg * kDegToRad, Eigen::Vector3d::UnitX());
  s.translation = t;
  return s;
}

// The seed: the truth followed by a scaling by `scale_factor` and a turn by `yaw_deg` about the
// middle of the street, and a move by `offset` (map frame).
Similarity3 Perturb(const Similarity3& truth,
                    const Eigen::Vector3d& offset,
                    double yaw_deg,
                    double scale_factor) {
  const Eigen::Vector3d pivot(0.0, 0.0, 1.0);
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(yaw_deg * kDegToRad, Eigen::Vector3d::UnitZ()));
  Similarity3 s;
  s.scale = scale_factor * truth.scale;
  s.rotation = turn * truth.rotation;
  s.translation = scale_factor * (turn * (truth.translation - pivot)) + pivot + offset;
  return s;
}

double RotationErrorDeg(const Similarity3& a, const Similarity3& b) {
  return a.rotation.angularDistance(b.rotation) / kDegToRad;
}

// Map points themselves, in a VO frame of another scale: each pairs with itself at the truth,
// so the registration must land on it to rounding.
TEST(StructureRegistration, RecoversExactSimilarity) {
  const Street street = MakeStreet(0.2, true);
  const Similarity3 map_from_world = MakeSimilarity(7.5, 33.0, -2.0, {101.0, -42.0, 3.0});
  const Similarity3 world_from_map = map_from_world.Inverse();
  std::vector<Eigen::Vector3d> structure;
  for (size_t i = 0; i < street.points.size(); i += 7) {
    structure.push_back(world_from_map * street.points[i]);
  }
  const Similarity3 seed = Perturb(map_from_world, {2.0, -2.0, 0.5}, 5.0, 1.08);
  StructureRegistrationOptions options;
  options.converged_m = 1e-10;
  options.max_iterations_per_level = 30;
  StructureMap map(ToCloud(street.points), options);
  const StructureRegistration r =
      RegisterStructure(structure, map, seed, Eigen::Vector3d::UnitX(), options);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(r.map_from_world.scale, map_from_world.scale, 1e-6 * map_from_world.scale);
  EXPECT_LT(RotationErrorDeg(r.map_from_world, map_from_world), 1e-6);
  EXPECT_LT((r.map_from_world.translation - map_from_world.translation).norm(), 1e-6);
  EXPECT_EQ(r.num_inliers, static_cast<int>(structure.size()));
  EXPECT_LT(r.rms_m, 1e-6);
  EXPECT_GT(r.along_information, 0.02);
  EXPECT_EQ(r.along_ambiguity_m, 0.0);
  EXPECT_LT(r.along_sigma_m, 1e-6);
}

// Independent samples of the surfaces with 2 cm noise, 20 % outliers, a car that moved (in the
// structure 3 m from where the map has it), a car the map has and the structure does not; seed
// 3 m and 5 degrees off, scale 8 % off.
TEST(StructureRegistration, RobustToOutliersMovingObjectsAndPriorNoise) {
  const Street map_street = MakeStreet(0.1, true);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Street surfaces = MakeStreet(0.37, false);
  const Similarity3 map_from_world = MakeSimilarity(0.8, -120.0, 1.0, {-5.0, 8.0, 1.6});
  const Similarity3 world_from_map = map_from_world.Inverse();
  std::vector<Eigen::Vector3d> structure;
  for (const Eigen::Vector3d& p : surfaces.points) {
    if (unit(rng) < 0.5) continue;
    structure.push_back(world_from_map * (p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))));
  }
  const size_t good = structure.size();
  Street moved;
  moved.AddBox({-3, 1.0, 0}, {4.2, 1.8, 1.5}, 0.3);  // a car driving ahead: not in the map
  for (const Eigen::Vector3d& p : moved.points) structure.push_back(world_from_map * p);
  for (size_t i = 0; i < good / 5; ++i) {
    const Eigen::Vector3d p(-20 + 40 * unit(rng), -10 + 20 * unit(rng), 12 * unit(rng));
    structure.push_back(world_from_map * p);
  }
  for (const auto& [offset, yaw] : std::vector<std::pair<Eigen::Vector3d, double>>{
           {{3.0, 0.0, 0.0}, 5.0}, {{-2.1, 2.1, 0.3}, -5.0}, {{0.0, -3.0, -0.3}, 4.0}}) {
    SCOPED_TRACE(testing::Message() << "seed offset " << offset.transpose() << " yaw " << yaw);
    const Similarity3 seed = Perturb(map_from_world, offset, yaw, 1.08);
    StructureRegistrationOptions options;
    StructureMap map(ToCloud(map_street.points), options);
    const StructureRegistration r =
        RegisterStructure(structure, map, seed, Eigen::Vector3d::UnitX(), options);
    ASSERT_TRUE(r.success) << r.message;
    EXPECT_NEAR(r.map_from_world.scale / map_from_world.scale, 1.0, 0.005);
    EXPECT_LT(RotationErrorDeg(r.map_from_world, map_from_world), 0.1);
    // The error at the structure (the camera is among it): the map position of the origin of a
    // world point in the middle of the street.
    const Eigen::Vector3d middle = world_from_map * Eigen::Vector3d(0, 0, 1.5);
    EXPECT_LT(((r.map_from_world * middle) - (map_from_world * middle)).norm(), 0.02);
    EXPECT_GT(r.inlier_share, 0.6);
    EXPECT_LT(r.inlier_share, 0.9);  // the outliers and the moving car are not inliers
    EXPECT_LT(r.rms_m, 0.05);
    // The windows fix the street along x: a move by the finest distance loses points.
    EXPECT_EQ(r.along_ambiguity_m, 0.0);
    EXPECT_GT(r.along_points_on_surface, 0);
  }
}

// A street of the road and plain facades only: the registration cannot tell where along it the
// structure belongs, and says so.
TEST(StructureRegistration, ReportsDegenerateAlongTheRoad) {
  Street plain;
  plain.AddRect({-20, -7, 0}, {40, 0, 0}, {0, 14, 0}, 0.2);
  plain.AddRect({-20, -7, 0}, {40, 0, 0}, {0, 0, 6}, 0.2);
  plain.AddRect({-20, 7, 0}, {40, 0, 0}, {0, 0, 6}, 0.2);
  const Similarity3 truth = MakeSimilarity(2.0, 10.0, 0.0, {1.0, 2.0, 0.0});
  std::vector<Eigen::Vector3d> structure;
  for (size_t i = 0; i < plain.points.size(); i += 11) {
    if (std::abs(plain.points[i].x()) < 15) structure.push_back(truth.Inverse() * plain.points[i]);
  }
  StructureRegistrationOptions options;
  StructureMap map(ToCloud(plain.points), options);
  const StructureRegistration r = RegisterStructure(
      structure, map, Perturb(truth, {2.0, 0.0, 0.0}, 0.0, 1.0), Eigen::Vector3d::UnitX(), options);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_LT(r.along_information, 1e-3);
  // Moved anywhere along it within the search's reach, as many points lie on the map (the
  // profile steps by the finest distance).
  const double finest = options.max_distances_m.back();
  EXPECT_GT(r.along_ambiguity_m, options.search_along_m - finest);
  EXPECT_GT(r.along_sigma_m, 0.5 * (options.search_along_m - finest));
}

TEST(StructureRegistration, TooFewPointsIsAValue) {
  Street street = MakeStreet(0.5, false);
  StructureRegistrationOptions options;
  StructureMap map(ToCloud(street.points), options);
  const std::vector<Eigen::Vector3d> few(street.points.begin(), street.points.begin() + 5);
  const StructureRegistration r =
      RegisterStructure(few, map, Similarity3(), Eigen::Vector3d::UnitX(), options);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("5 structure points"), std::string::npos) << r.message;
  options.max_distances_m = {0.5, 1.0};
  EXPECT_NE(ErrorOf([&] { options.Check(); }).find("coarse to fine"), std::string::npos);
}

}  // namespace
}  // namespace epiloc
