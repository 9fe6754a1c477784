#include "epiloc/geometry/epipole.h"

#include <algorithm>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace epiloc {
namespace {

Camera MakeCamera(int width, int height, double f) {
  Camera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = camera.fy = f;
  camera.cx = width / 2.0 - 0.5;
  camera.cy = height / 2.0 - 0.5;
  return camera;
}

// A street: points on two facades (x = -6 m and x = +7 m) and the road (y = +1.5 m, camera frame
// y down), 5-60 m ahead of the query camera at the origin.
std::vector<Eigen::Vector3d> StreetPoints(std::mt19937_64& rng, int n) {
  std::uniform_real_distribution<double> z(5, 60), height(-8, 1.4), lateral(-5.5, 6.5), which(0, 3);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const int k = static_cast<int>(which(rng));
    if (k == 0) points.emplace_back(-6.0, height(rng), z(rng));
    else if (k == 1) points.emplace_back(7.0, height(rng), z(rng));
    else points.emplace_back(lateral(rng), 1.5, z(rng));
  }
  return points;
}

struct Pair {
  std::vector<Eigen::Vector2d> query, db;
};

// Projects the points into the query camera (identity pose) and a database camera whose centre
// is `db_center` in the query frame with rotation db_from_query, keeping points inside both
// images, with Gaussian pixel noise.
Pair Project(const std::vector<Eigen::Vector3d>& points,
             const Camera& query_camera,
             const Camera& db_camera,
             const Eigen::Vector3d& db_center,
             const Eigen::Matrix3d& db_from_query,
             double noise_px,
             std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, noise_px);
  Pair pair;
  for (const Eigen::Vector3d& x : points) {
    const Eigen::Vector3d in_db = db_from_query * (x - db_center);
    if (x.z() < 1 || in_db.z() < 1) continue;
    const Eigen::Vector2d a = query_camera.Project(x) + Eigen::Vector2d(noise(rng), noise(rng));
    const Eigen::Vector2d b = db_camera.Project(in_db) + Eigen::Vector2d(noise(rng), noise(rng));
    if (a.x() < 0 || a.y() < 0 || a.x() > query_camera.width - 1 || a.y() > query_camera.height - 1)
      continue;
    if (b.x() < 0 || b.y() < 0 || b.x() > db_camera.width - 1 || b.y() > db_camera.height - 1)
      continue;
    pair.query.push_back(a);
    pair.db.push_back(b);
  }
  return pair;
}

Eigen::Matrix3d SmallRotation(double yaw_deg, double pitch_deg) {
  return (Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(pitch_deg * M_PI / 180, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

class EpipoleModels : public ::testing::TestWithParam<EpipoleOptions::Model> {};

TEST_P(EpipoleModels, HorizontalEpipoleMatchesEquationOne) {
  std::mt19937_64 rng(11);
  const Camera query = MakeCamera(1242, 375, 721.5);
  const Camera db = MakeCamera(800, 400, 600.0);  // another camera on the database side
  EpipoleOptions options;
  options.model = GetParam();
  // The calibrated 5-parameter model is markedly more accurate than the 7-parameter F.
  const double tolerance = options.model == EpipoleOptions::Model::kEssential ? 0.025 : 0.05;
  for (const double q_z : {-6.0, -2.5, -0.8, 0.9, 3.0, 7.0}) {
    const Eigen::Vector3d center(0.54, 0.02, q_z);
    const Pair pair = Project(StreetPoints(rng, 600), query, db, center, SmallRotation(1.5, -0.5),
                              0.3, rng);
    const EpipoleResult result = EstimateEpipole(pair.query, query, pair.db, db, options);
    ASSERT_TRUE(result.valid) << result.failure << " q_z " << q_z;
    const double expected_e_x = query.fx * center.x() / center.z();  // eq. (1) with signs
    const double expected_d = EpipolarDistance(center, query.fx);
    EXPECT_NEAR(result.distance, expected_d, tolerance * expected_d) << "q_z " << q_z;
    EXPECT_NEAR(std::abs(result.e_x_px), std::abs(expected_e_x), tolerance * std::abs(expected_e_x))
        << "q_z " << q_z;
    EXPECT_EQ(result.signed_distance > 0, q_z > 0) << "q_z " << q_z;
    EXPECT_GT(result.db_center_in_query.dot(center.normalized()), 0.999) << "q_z " << q_z;
    EXPECT_GT(result.num_inliers, 0.9 * result.num_matches);
  }
}

TEST_P(EpipoleModels, DistanceGrowsLinearlyWithAlongRoadDistance) {
  std::mt19937_64 rng(5);
  const Camera camera = MakeCamera(1242, 375, 721.5);
  EpipoleOptions options;
  options.model = GetParam();
  std::vector<double> d;
  for (const double q_z : {1.0, 2.0, 4.0}) {
    const Pair pair = Project(StreetPoints(rng, 600), camera, camera,
                              Eigen::Vector3d(-0.7, 0.0, q_z), Eigen::Matrix3d::Identity(), 0.2,
                              rng);
    const EpipoleResult result = EstimateEpipole(pair.query, camera, pair.db, camera, options);
    ASSERT_TRUE(result.valid) << result.failure;
    d.push_back(result.distance);
  }
  EXPECT_NEAR(d[1] / d[0], 2.0, 0.06);
  EXPECT_NEAR(d[2] / d[0], 4.0, 0.12);
}

INSTANTIATE_TEST_SUITE_P(Models,
                         EpipoleModels,
                         ::testing::Values(EpipoleOptions::Model::kEssential,
                                           EpipoleOptions::Model::kFundamental));

TEST(Epipole, PureRotationIsMissingNotMadeUp) {
  std::mt19937_64 rng(3);
  const Camera camera = MakeCamera(1242, 375, 721.5);
  const Pair pair = Project(StreetPoints(rng, 500), camera, camera, Eigen::Vector3d::Zero(),
                            SmallRotation(4.0, 1.0), 0.2, rng);
  const EpipoleResult result = EstimateEpipole(pair.query, camera, pair.db, camera, EpipoleOptions());
  EXPECT_FALSE(result.valid);
}

TEST(Epipole, TooFewMatchesOrInliersAreMissing) {
  std::mt19937_64 rng(4);
  const Camera camera = MakeCamera(640, 480, 500);
  Pair pair = Project(StreetPoints(rng, 12), camera, camera, Eigen::Vector3d(0.5, 0, 3),
                      Eigen::Matrix3d::Identity(), 0.2, rng);
  EpipoleResult result = EstimateEpipole(pair.query, camera, pair.db, camera, EpipoleOptions());
  EXPECT_FALSE(result.valid);
  EXPECT_EQ(result.failure, "too few matches");

  // Random correspondences: no geometry explains them.
  std::uniform_real_distribution<double> x(0, 639), y(0, 479);
  pair.query.clear();
  pair.db.clear();
  for (int i = 0; i < 300; ++i) {
    pair.query.emplace_back(x(rng), y(rng));
    pair.db.emplace_back(x(rng), y(rng));
  }
  result = EstimateEpipole(pair.query, camera, pair.db, camera, EpipoleOptions());
  EXPECT_FALSE(result.valid) << "inliers " << result.num_inliers;
}

TEST(Epipole, RansacStopsAtTheSmallestAcceptableInlierShare) {
  EpipoleOptions options;  // 20 inliers, a share of 0.2, confidence 0.999, at most 2000
  // 32 matches: an accepted pair has >= 20/32 inliers; one all-inlier 5-sample in 69 draws
  // with probability 0.999: 1 - (1 - 0.625^5)^69 >= 0.999 > 1 - (1 - 0.625^5)^68.
  EXPECT_EQ(RansacIterationCap(options, 32), 69);
  // Many matches: the share of 0.2 would need 21,583 draws; the limit holds.
  EXPECT_EQ(RansacIterationCap(options, 1000), 2000);
  // Exactly the minimum: every match must be an inlier, one draw decides.
  EXPECT_EQ(RansacIterationCap(options, 20), 1);
  options.model = EpipoleOptions::Model::kFundamental;  // 7-point samples
  EXPECT_EQ(RansacIterationCap(options, 32), 182);

  // The cap does not lose a pair that has the share: 40 matches, 26 of them true (0.65).
  std::mt19937_64 rng(11);
  const Camera camera = MakeCamera(640, 480, 500);
  Pair pair = Project(StreetPoints(rng, 60), camera, camera, Eigen::Vector3d(0.6, 0, 4),
                      SmallRotation(1.0, 0.0), 0.3, rng);
  ASSERT_GE(pair.query.size(), 26u);
  pair.query.resize(26);
  pair.db.resize(26);
  std::uniform_real_distribution<double> x(0, 639), y(0, 479);
  for (int i = 0; i < 14; ++i) {
    pair.query.emplace_back(x(rng), y(rng));
    pair.db.emplace_back(x(rng), y(rng));
  }
  options.model = EpipoleOptions::Model::kEssential;
  ASSERT_LT(RansacIterationCap(options, 40), 1000);  // the explicit-parameter path of OpenCV
  for (int seed = 0; seed < 20; ++seed) {
    // Other orders of the same matches: other RANSAC draws.
    std::shuffle(pair.query.begin(), pair.query.end(), std::mt19937_64(seed));
    std::shuffle(pair.db.begin(), pair.db.end(), std::mt19937_64(seed));
    const EpipoleResult result = EstimateEpipole(pair.query, camera, pair.db, camera, options);
    EXPECT_TRUE(result.valid) << "order " << seed << ": " << result.failure;
    EXPECT_GE(result.num_inliers, 24) << "order " << seed;
  }
}

TEST(Epipole, EquationOneOnExactGeometry) {
  // |e_x| = f |q_x| / |q_z|: 721.5 * 0.54 / 2 = 194.805 px; d = 1 / 194.805.
  EXPECT_DOUBLE_EQ(EpipolarDistance(Eigen::Vector3d(0.54, 0.0, 2.0), 721.5), 2.0 / (721.5 * 0.54));
  EXPECT_DOUBLE_EQ(EpipolarDistance(Eigen::Vector3d(-0.54, 0.1, -2.0), 721.5),
                   2.0 / (721.5 * 0.54));
  EXPECT_TRUE(std::isinf(EpipolarDistance(Eigen::Vector3d(0.0, 0.0, 2.0), 721.5)));
}

}  // namespace
}  // namespace epiloc
