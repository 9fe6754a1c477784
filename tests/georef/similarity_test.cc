#include "epiloc/georef/similarity.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "test_util.h"

namespace epiloc {
namespace {

// A rotation about a random axis by a random angle in [0, pi).
Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> angle(0.0, M_PI);
  const Eigen::Vector3d axis = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle(rng), axis));
}

// `n` points uniform in a box of `half_size_m` about `centre`.
std::vector<Eigen::Vector3d> RandomPoints(std::mt19937_64& rng,
                                          int n,
                                          double half_size_m,
                                          const Eigen::Vector3d& centre = Eigen::Vector3d::Zero()) {
  std::uniform_real_distribution<double> uniform(-half_size_m, half_size_m);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    points.push_back(centre + Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng)));
  }
  return points;
}

std::vector<Eigen::Vector3d> Apply(const Sim3d& sim, const std::vector<Eigen::Vector3d>& points) {
  std::vector<Eigen::Vector3d> out;
  for (const Eigen::Vector3d& p : points) out.push_back(sim * p);
  return out;
}

double AngleRad(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return Eigen::AngleAxisd(a.conjugate() * b).angle();
}

Sim3d MakeSim(double scale, const Eigen::Quaterniond& rotation, const Eigen::Vector3d& t) {
  Sim3d sim;
  sim.scale = scale;
  sim.rotation = rotation;
  sim.translation = t;
  return sim;
}

TEST(Similarity, ApplyMapPoseAndInverse) {
  const Sim3d sim =
      MakeSim(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(10, 20, 30));
  // x_in_b = s R x_in_a + t: (1, 0, 0) -> R -> (0, 1, 0) -> *2 -> (0, 2, 0) -> + t.
  EXPECT_LT((sim * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(10, 22, 30)).norm(), 1e-12);
  const Sim3d inverse = sim.Inverse();
  EXPECT_DOUBLE_EQ(inverse.scale, 0.5);
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(-7, 0.5, 100)}) {
    EXPECT_LT((inverse * (sim * x) - x).norm(), 1e-12);
    EXPECT_LT((sim * (inverse * x) - x).norm(), 1e-12);
  }
  // MapPose: the centre is mapped with the scale, the rotation composed without it.
  const Rigid3d a_from_cam(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())),
                           Eigen::Vector3d(1, 0, 0));
  const Rigid3d b_from_cam = sim.MapPose(a_from_cam);
  EXPECT_LT((b_from_cam.translation - Eigen::Vector3d(10, 22, 30)).norm(), 1e-12);
  EXPECT_LT(AngleRad(b_from_cam.rotation, sim.rotation * a_from_cam.rotation), 1e-12);
}

TEST(Similarity, ExactDataIsRecoveredToRoundOff) {
  std::mt19937_64 rng(7);
  for (const double scale : {0.013, 1.0, 37.5}) {
    const Sim3d truth = MakeSim(scale, RandomRotation(rng), Eigen::Vector3d(250.0, -1300.0, 42.0));
    // VO-like source: a few tens of units about an offset origin.
    const std::vector<Eigen::Vector3d> source =
        RandomPoints(rng, 20, 30.0, Eigen::Vector3d(5.0, -3.0, 12.0));
    const auto fit = FitSim3(source, Apply(truth, source));
    ASSERT_TRUE(fit.has_value()) << "scale " << scale;
    EXPECT_NEAR(fit->scale / truth.scale, 1.0, 1e-9);
    EXPECT_LT(AngleRad(fit->rotation, truth.rotation), 1e-9);
    EXPECT_LT((fit->translation - truth.translation).norm(), 1e-9 * truth.translation.norm());
    const FitResiduals r = Residuals(*fit, source, Apply(truth, source));
    EXPECT_LT(r.max_m, 1e-9);
  }
}

TEST(Similarity, ThreePointsAndPlanarPointsAreEnough) {
  std::mt19937_64 rng(11);
  const Sim3d truth = MakeSim(3.0, RandomRotation(rng), Eigen::Vector3d(1.0, 2.0, 3.0));
  const std::vector<Eigen::Vector3d> triangle = {{0, 0, 0}, {10, 0, 0}, {0, 5, 0}};
  auto fit = FitSim3(triangle, Apply(truth, triangle));
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->scale, 3.0, 1e-9);
  EXPECT_LT(AngleRad(fit->rotation, truth.rotation), 1e-9);
  EXPECT_LT((fit->translation - truth.translation).norm(), 1e-9);
  // A flat road: all points in one plane (third singular value zero), still a proper rotation
  // (no reflection through the plane).
  std::vector<Eigen::Vector3d> plane = RandomPoints(rng, 30, 50.0);
  for (Eigen::Vector3d& p : plane) p.z() = 0.0;
  fit = FitSim3(plane, Apply(truth, plane));
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->scale, 3.0, 1e-9);
  EXPECT_LT(AngleRad(fit->rotation, truth.rotation), 1e-9);
  EXPECT_NEAR(fit->rotation.toRotationMatrix().determinant(), 1.0, 1e-12);
}

TEST(Similarity, NoisyDataGivesACloseFit) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);  // 5 cm per axis on the target
  const Sim3d truth = MakeSim(8.0, RandomRotation(rng), Eigen::Vector3d(-20.0, 400.0, 3.0));
  const std::vector<Eigen::Vector3d> source = RandomPoints(rng, 200, 10.0);  // 160 m wide target
  std::vector<Eigen::Vector3d> target = Apply(truth, source);
  for (Eigen::Vector3d& p : target) p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  const auto fit = FitSim3(source, target);
  ASSERT_TRUE(fit.has_value());
  // Expected errors: scale ~ sigma / (spread * sqrt(n)) ~ 1e-4 relative, rotation ~ 1e-4 rad.
  EXPECT_NEAR(fit->scale / truth.scale, 1.0, 1e-3);
  EXPECT_LT(AngleRad(fit->rotation, truth.rotation), 1e-3);
  EXPECT_LT((fit->translation - truth.translation).norm(), 0.05);
  // The residuals are the noise: rms ~ sqrt(3) * 0.05 m (less the 7 fitted parameters).
  const FitResiduals r = Residuals(*fit, source, target);
  EXPECT_NEAR(r.rms_m, std::sqrt(3.0) * 0.05, 0.01);
  EXPECT_GE(r.max_m, r.rms_m);
  EXPECT_LT(r.max_m, 0.3);
  // The fit is the least-squares one: the true similarity is no better.
  EXPECT_LE(r.rms_m, Residuals(truth, source, target).rms_m);
}

TEST(Similarity, DegenerateInputGivesNoFit) {
  const Sim3d truth =
      MakeSim(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY())),
              Eigen::Vector3d(1, 1, 1));
  // Too few pairs.
  EXPECT_FALSE(FitSim3({}, {}).has_value());
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 2, 3}};
  EXPECT_FALSE(FitSim3(two, Apply(truth, two)).has_value());
  // All points equal.
  const std::vector<Eigen::Vector3d> same(5, Eigen::Vector3d(4, 5, 6));
  EXPECT_FALSE(FitSim3(same, Apply(truth, same)).has_value());
  // Collinear: a straight drive; the rotation about the line is free.
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 10; ++i)
    line.push_back(Eigen::Vector3d(1, 2, 3) + i * Eigen::Vector3d(0.3, 0.1, 2.0));
  EXPECT_FALSE(FitSim3(line, Apply(truth, line)).has_value());
  // Nearly collinear: a 1 mm bump on an 18 m line is below the default spread ratio (1e-3)...
  std::vector<Eigen::Vector3d> bumped = line;
  bumped[5] += Eigen::Vector3d(0.001, 0.0, 0.0);
  EXPECT_FALSE(FitSim3(bumped, Apply(truth, bumped)).has_value());
  // ... and accepted with a smaller one; 1 m off the line is accepted by default.
  EXPECT_TRUE(FitSim3(bumped, Apply(truth, bumped), 1e-6).has_value());
  bumped[5] += Eigen::Vector3d(1.0, 0.0, 0.0);
  const auto fit = FitSim3(bumped, Apply(truth, bumped));
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->scale, 2.0, 1e-9);
  // Mismatched sizes are a programming error.
  ExpectError([&] { FitSim3(line, two); }, {"10 source but 2 target"});
}

TEST(Similarity, ResidualsOfKnownOffsets) {
  const Sim3d identity;
  const std::vector<Eigen::Vector3d> source = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  std::vector<Eigen::Vector3d> target = source;
  target[1].x() += 3.0;
  target[2] += Eigen::Vector3d(0, 0, 4.0);
  const FitResiduals r = Residuals(identity, source, target);
  EXPECT_DOUBLE_EQ(r.max_m, 4.0);
  EXPECT_DOUBLE_EQ(r.rms_m, std::sqrt((9.0 + 16.0) / 4.0));
  const FitResiduals none = Residuals(identity, {}, {});
  EXPECT_EQ(none.rms_m, 0.0);
  EXPECT_EQ(none.max_m, 0.0);
}

}  // namespace
}  // namespace epiloc

namespace epiloc {
namespace {

// With the rotations given, exact data is recovered, also from points on one line (two pairs).
TEST(Similarity, RotationsFixWhatCollinearPointsLeaveOpen) {
  std::mt19937_64 rng(13);
  const Sim3d truth = MakeSim(2.5, RandomRotation(rng), Eigen::Vector3d(-4.0, 7.0, 1.0));
  std::vector<Eigen::Vector3d> source = RandomPoints(rng, 12, 20.0, Eigen::Vector3d(1, 2, 3));
  std::vector<Eigen::Quaterniond> rotations(source.size(), truth.rotation);
  auto fit = FitSim3(source, Apply(truth, source), rotations);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->scale, truth.scale, 1e-9);
  EXPECT_LT(AngleRad(fit->rotation, truth.rotation), 1e-9);
  EXPECT_LT((fit->translation - truth.translation).norm(), 1e-9);
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {0, 0, 10}};
  fit = FitSim3(line, Apply(truth, line), {truth.rotation, truth.rotation});
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->scale, truth.scale, 1e-9);
  EXPECT_LT(AngleRad(fit->rotation, truth.rotation), 1e-9);
  EXPECT_FALSE(FitSim3({line[0]}, {line[0]}, {truth.rotation}).has_value());
  EXPECT_FALSE(FitSim3({line[0], line[0]}, {line[0], line[1]}, {truth.rotation, truth.rotation})
                   .has_value());  // no spread in the source
  EXPECT_THROW(FitSim3(line, line, {truth.rotation}), Error);  // one rotation per pair
}

}  // namespace
}  // namespace epiloc
