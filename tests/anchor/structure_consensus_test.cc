// The structure anchor's consensus passes on exact similarities: the neighbours' disagreement
// along the road, the consensus placement, the drift along the path between two anchors, the
// rotation consensus and the orientation it gives the camera.
#include "epiloc/anchor/structure_anchor.h"

#include <cmath>
#include <optional>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/core/angles.h"
#include "structure_anchor_internal.h"
#include "test_util.h"

namespace epiloc {
namespace {

// Six anchors 5 m apart along a VO trajectory scaled 2x into the map: with exact similarities
// each is placed where its neighbours put it; one similarity 1 m off along the road is that far
// (its share along the anchors' line) from its neighbours' median (the median ignores it in
// theirs); an anchor of another segment, or with fewer than three neighbours within half the
// window, is not judged.
TEST(StructureAnchor, NeighbourDisagreementFindsTheAnchorItsNeighboursPlaceElsewhere) {
  Similarity3 exact;
  exact.scale = 2.0;
  exact.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  exact.translation = Eigen::Vector3d(10, -4, 1);
  std::vector<PlacedAnchor> anchors;
  for (int i = 0; i < 6; ++i) {
    PlacedAnchor a;
    a.map_from_world = exact;
    a.vo_centre = Eigen::Vector3d(2.5 * i, 0.1 * i, 0.0);
    a.map_centre = exact * a.vo_centre;
    anchors.push_back(a);
  }
  const Eigen::Vector3d along = exact.rotation * Eigen::Vector3d::UnitX();
  anchors[2].map_from_world.translation += along;
  anchors[2].map_centre += along;
  // The road runs along the anchors' centres, (2.5, 0.1) in the VO world: the move's share
  // along it.
  const double moved = std::cos(std::atan2(0.1, 2.5));
  std::vector<std::optional<double>> off = NeighbourDisagreement(anchors, 40.0);
  ASSERT_EQ(off.size(), anchors.size());
  for (size_t i = 0; i < off.size(); ++i) {
    ASSERT_TRUE(off[i].has_value()) << i;
    EXPECT_NEAR(*off[i], i == 2 ? moved : 0.0, 1e-9) << i;
  }
  // Another segment is not a neighbour: anchor 5 alone in its segment is not judged.
  anchors[5].segment = 1;
  off = NeighbourDisagreement(anchors, 40.0);
  EXPECT_FALSE(off[5].has_value());
  EXPECT_TRUE(off[0].has_value());
  // A window of 24 m: neighbours within 12 m of the anchor's own map centre. Anchor 0 (at 0 m
  // along the road) has 1 (5 m) and 2 (11 m) only; anchor 2 (moved to 11 m) has 0, 1, 3 and 4.
  off = NeighbourDisagreement(anchors, 24.0);
  EXPECT_FALSE(off[0].has_value());
  ASSERT_TRUE(off[2].has_value());
  EXPECT_NEAR(*off[2], moved, 1e-9);
}

// Seven anchors 5 m apart; the neighbours of the middle one (exact) moved along the road by
// -1, -0.6, 0, 0, +0.6, +1 m: their median places it where it is (no disagreement), but only two
// of the six within a claim of 0.3 m: a third. Exact neighbours: all of them.
TEST(StructureAnchor, NeighbourAgreementCountsThePlacementsWithinTheClaim) {
  Similarity3 exact;
  exact.scale = 2.0;
  exact.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitZ()));
  exact.translation = Eigen::Vector3d(4, 2, -1);
  std::vector<PlacedAnchor> anchors;
  for (int i = 0; i < 7; ++i) {
    PlacedAnchor a;
    a.map_from_world = exact;
    a.vo_centre = Eigen::Vector3d(2.5 * i, 0.0, 0.0);
    a.map_centre = exact * a.vo_centre;
    anchors.push_back(a);
  }
  std::vector<std::optional<double>> share = NeighbourAgreement(anchors, 40.0, 0.3);
  ASSERT_EQ(share.size(), anchors.size());
  for (size_t i = 0; i < share.size(); ++i) {
    ASSERT_TRUE(share[i].has_value()) << i;
    EXPECT_DOUBLE_EQ(*share[i], 1.0) << i;
  }
  const Eigen::Vector3d along = exact.rotation * Eigen::Vector3d::UnitX();
  const std::vector<double> moves = {-1.0, -0.6, 0.0, 0.0, 0.6, 1.0};
  for (int i = 0, m = 0; i < 7; ++i) {
    if (i == 3) continue;
    anchors[static_cast<size_t>(i)].map_from_world.translation += moves[m] * along;
    anchors[static_cast<size_t>(i)].map_centre += moves[m] * along;
    ++m;
  }
  const std::vector<std::optional<double>> off = NeighbourDisagreement(anchors, 40.0);
  ASSERT_TRUE(off[3].has_value());
  EXPECT_NEAR(*off[3], 0.0, 1e-9);
  share = NeighbourAgreement(anchors, 40.0, 0.3);
  ASSERT_TRUE(share[3].has_value());
  EXPECT_NEAR(*share[3], 2.0 / 6.0, 1e-12);
  // Within a claim of 0.7 m: four of six.
  share = NeighbourAgreement(anchors, 40.0, 0.7);
  EXPECT_NEAR(*share[3], 4.0 / 6.0, 1e-12);
  // Fewer than three neighbours: not judged.
  EXPECT_FALSE(NeighbourAgreement(anchors, 12.0, 0.3)[0].has_value());
}

// The consensus placement: six anchors 2.5 m apart along a VO trajectory scaled 2x into the map,
// one of them 1 m off along the road. Each is placed at the median of its neighbours'
// placements, itself included: the exact ones where they are (the one moved similarity places
// them 1 m off, and the median ignores it), the moved one back where its neighbours put it.
// Fewer than three within half the window (another segment, a short window) leave it unplaced.
TEST(StructureAnchor, ConsensusCentresPutEachAnchorWhereMostOfItsNeighboursPlaceIt) {
  Similarity3 exact;
  exact.scale = 2.0;
  exact.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitZ()));
  exact.translation = Eigen::Vector3d(-3, 8, 0.5);
  std::vector<PlacedAnchor> anchors;
  std::vector<Eigen::Vector3d> truth;
  for (int i = 0; i < 6; ++i) {
    PlacedAnchor a;
    a.map_from_world = exact;
    a.vo_centre = Eigen::Vector3d(2.5 * i, 0.2 * i, 0.05 * i);
    a.map_centre = exact * a.vo_centre;
    truth.push_back(a.map_centre);
    anchors.push_back(a);
  }
  const Eigen::Vector3d along = exact.rotation * Eigen::Vector3d::UnitX();
  anchors[2].map_from_world.translation += along;
  anchors[2].map_centre += along;
  std::vector<std::optional<Eigen::Vector2d>> centres = ConsensusCentres(anchors, 40.0);
  ASSERT_EQ(centres.size(), anchors.size());
  for (size_t i = 0; i < centres.size(); ++i) {
    ASSERT_TRUE(centres[i].has_value()) << i;
    EXPECT_NEAR((*centres[i] - truth[i].head<2>()).norm(), 0.0, 1e-9) << i;
  }
  // Anchors 3-5 in another segment: 0-2 have three (themselves included), 3-5 three.
  for (int i = 3; i < 6; ++i) anchors[static_cast<size_t>(i)].segment = 1;
  centres = ConsensusCentres(anchors, 40.0);
  for (size_t i = 0; i < centres.size(); ++i) ASSERT_TRUE(centres[i].has_value()) << i;
  EXPECT_NEAR((*centres[2] - truth[2].head<2>()).norm(), 0.0, 1e-9);
  // Anchor 5 alone: none.
  anchors[5].segment = 2;
  centres = ConsensusCentres(anchors, 40.0);
  EXPECT_FALSE(centres[5].has_value());
  EXPECT_FALSE(centres[4].has_value());
  // A window of 8 m: neighbours within 4 m, anchor 0 has 1 (5 m off: no) -> none.
  anchors.assign(anchors.begin(), anchors.begin() + 3);
  for (PlacedAnchor& a : anchors) a.segment = 0;
  centres = ConsensusCentres(anchors, 8.0);
  EXPECT_FALSE(centres[0].has_value());
}

// The disagreement is measured along the road only (the claim of an ok anchor): an anchor moved
// 1 m across the road and 0.3 m along it is 0.3 m off, whether the road's direction comes from
// the anchors' map centres or from the VO path (here a path along the world's y axis, turned by
// the similarity: the anchors' own centres are spread along x, so the path must win).
TEST(StructureAnchor, NeighbourDisagreementIsMeasuredAlongTheRoad) {
  Similarity3 exact;
  exact.scale = 1.5;
  exact.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitZ()));
  exact.translation = Eigen::Vector3d(3, 8, 0);
  std::vector<PlacedAnchor> anchors;
  for (int i = 0; i < 6; ++i) {
    PlacedAnchor a;
    a.map_from_world = exact;
    a.vo_centre = Eigen::Vector3d(4.0 * i, 0.0, 0.0);
    a.map_centre = exact * a.vo_centre;
    anchors.push_back(a);
  }
  const Eigen::Vector3d along = exact.rotation * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d across = exact.rotation * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d move = 0.3 * along + 1.0 * across;
  anchors[3].map_from_world.translation += move;
  anchors[3].map_centre += move;
  std::vector<std::optional<double>> off = NeighbourDisagreement(anchors, 40.0);
  ASSERT_TRUE(off[3].has_value());
  EXPECT_NEAR(*off[3], 0.3, 1e-9);

  // A VO path through the anchors' centres that heads along the world's y axis at anchor 3 (a
  // kink there): the road runs along `across` in the map, and the 1 m across is the 1 m along.
  auto path = std::make_shared<std::vector<Eigen::Vector3d>>();
  for (int i = 0; i < 6; ++i) path->push_back(anchors[static_cast<size_t>(i)].vo_centre);
  (*path)[2] = anchors[3].vo_centre - Eigen::Vector3d(0, 1, 0);
  (*path)[4] = anchors[3].vo_centre + Eigen::Vector3d(0, 1, 0);
  for (int i = 0; i < 6; ++i) {
    anchors[static_cast<size_t>(i)].path = path;
    anchors[static_cast<size_t>(i)].path_index = i;
  }
  off = NeighbourDisagreement(anchors, 40.0);
  ASSERT_TRUE(off[3].has_value());
  EXPECT_NEAR(*off[3], 1.0, 1e-9);
}

// Anchors along a VO path whose scale drifts: each anchor's fit is exact at its own camera with
// the drift (the scale s (1 + d x) at x metres along the path from it). Placed by the similarity
// alone, a neighbour 20 m away lands d x^2 / 2 = 0.6 m off (d = 0.3 % per metre); with the drift
// along the path between them (ScaleDriftPath), where it is, behind the anchor as well as ahead,
// and on a curve; without a shared path, or with no drift, the similarity alone.
TEST(StructureAnchor, PlacingANeighbourFollowsTheDriftAlongThePath) {
  const double s0 = 2.0, per_m = 0.003;
  // A VO path (world units) curving left, 0.5 units per pose; its metres at the start's scale.
  std::vector<Eigen::Vector3d> centres;
  for (int k = 0; k <= 60; ++k) {
    const double a = 0.004 * k;
    centres.emplace_back(0.5 * k * std::cos(a), 0.5 * k * std::sin(a), 0.0);
  }
  auto path = std::make_shared<std::vector<Eigen::Vector3d>>(centres);
  const Eigen::Quaterniond r(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  const Eigen::Vector3d t(10, -4, 1);
  // The true map position of camera k: the drifting scale integrated along the path from 0.
  std::vector<Eigen::Vector3d> truth(centres.size());
  truth[0] = t + s0 * (r * centres[0]);
  double metres = 0.0;
  for (size_t k = 1; k < centres.size(); ++k) {
    const Eigen::Vector3d step = centres[k] - centres[k - 1];
    const double step_m = s0 * step.norm();
    // The scale at the step's middle (its metres at the start's scale, to first order).
    const double scale = s0 * (1.0 + per_m * (metres + 0.5 * step_m));
    truth[k] = truth[k - 1] + scale * (r * step);
    metres += step_m;
  }
  // Anchor at camera k: the similarity exact there, at the local scale.
  const auto anchor = [&](int k) {
    PlacedAnchor a;
    double m = 0.0;
    for (int j = 1; j <= k; ++j) m += s0 * (centres[j] - centres[j - 1]).norm();
    a.map_from_world.scale = s0 * (1.0 + per_m * m);
    a.map_from_world.rotation = r;
    a.map_from_world.translation = truth[k] - a.map_from_world.scale * (r * centres[k]);
    a.vo_centre = centres[k];
    a.map_centre = truth[k];
    // Per metre at the local scale: s_k (1 + d_k s_k x) = s0 (1 + per_m (m + s0 x)).
    a.scale_drift_per_m = per_m / ((1.0 + per_m * m) * (1.0 + per_m * m));
    a.path = path;
    a.path_index = k;
    return a;
  };
  const PlacedAnchor at0 = anchor(0), at20 = anchor(20), at40 = anchor(40);
  // Camera 20 is 10 units (20 m) ahead of camera 0.
  EXPECT_NEAR((at0.Placing(at20) - truth[20]).norm(), 0.0, 0.01);
  EXPECT_NEAR((at40.Placing(at20) - truth[20]).norm(), 0.0, 0.01);  // behind
  EXPECT_NEAR((at20.Placing(at40) - truth[40]).norm(), 0.0, 0.01);
  EXPECT_NEAR((at20.Placing(at20) - truth[20]).norm(), 0.0, 1e-9);
  // The similarity alone: about d x^2 / 2 off.
  PlacedAnchor no_path = at0;
  no_path.path = nullptr;
  EXPECT_NEAR((no_path.Placing(at20) - truth[20]).norm(), per_m * 20.0 * 20.0 / 2.0, 0.05);
  PlacedAnchor no_drift = at0;
  no_drift.scale_drift_per_m = 0.0;
  EXPECT_NEAR((no_drift.Placing(at20) - (at0.map_from_world * centres[20])).norm(), 0.0, 1e-12);
}

// Seven anchors 5 m apart: their similarities' rotations turned about three axes by up to
// 0.2 degrees around a common one, plus one anchor 3 degrees off. Each anchor's consensus is the
// median of the rotations of the anchors within the window: with them all, every anchor gets the
// same rotation, within 0.2 degrees of the common one whatever the outlier's size (a mean would
// move by a seventh of it); with a window of 12 m, anchor 0 sees anchors 0-2 only; another
// segment is not a neighbour.
TEST(StructureAnchor, ConsensusRotationsTakeTheMedianOfTheOverlappingWindows) {
  const Eigen::Quaterniond common(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()));
  const auto turned = [&](double deg, const Eigen::Vector3d& axis) {
    return Eigen::Quaterniond(Eigen::AngleAxisd(deg * kDegToRad, axis.normalized())) * common;
  };
  const double turns[7] = {0.1, -0.2, 0.15, 0.0, -0.05, 0.2, -0.1};
  const Eigen::Vector3d axes[3] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
                                   Eigen::Vector3d::UnitZ()};
  std::vector<PlacedAnchor> anchors;
  for (int i = 0; i < 7; ++i) {
    PlacedAnchor a;
    a.map_from_world.rotation = turned(turns[i], axes[i % 3]);
    a.map_centre = Eigen::Vector3d(5.0 * i, 0.0, 0.0);
    anchors.push_back(a);
  }
  const auto angle_deg = [](const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
    return a.angularDistance(b) / kDegToRad;
  };
  for (const double outlier_deg : {3.0, 30.0}) {
    anchors[3].map_from_world.rotation = turned(outlier_deg, Eigen::Vector3d(1, 1, 0));
    const std::vector<Eigen::Quaterniond> c = ConsensusRotations(anchors, 40.0);
    ASSERT_EQ(c.size(), anchors.size());
    for (size_t i = 0; i < c.size(); ++i) {
      EXPECT_LT(angle_deg(c[i], common), 0.2) << outlier_deg << " " << i;
      EXPECT_LT(angle_deg(c[i], c[0]), 1e-9) << i;
    }
  }
  // A window of 12 m: anchor 0 has anchors 0, 1 and 2; their median is within their spread.
  anchors[3].map_from_world.rotation = common;
  std::vector<Eigen::Quaterniond> c = ConsensusRotations(anchors, 12.0);
  EXPECT_GT(angle_deg(c[0], c[6]), 1e-6);
  EXPECT_LT(angle_deg(c[0], common), 0.2);
  // Alone in its segment, an anchor keeps its own rotation.
  anchors[6].segment = 1;
  anchors[6].map_from_world.rotation = turned(5.0, Eigen::Vector3d::UnitZ());
  c = ConsensusRotations(anchors, 40.0);
  EXPECT_LT(angle_deg(c[6], anchors[6].map_from_world.rotation), 1e-9);
  EXPECT_LT(angle_deg(c[5], common), 0.2);
}

// The last pass turns each posed anchor's camera by its orientation consensus composed with its
// own VO orientation (the structure was registered with the longer radius's rotation): exact
// rotation, the centre and WGS-84 position kept, the ENU rotation written to match; an anchor
// without a pose or without an orientation keeps what it has; no orientations: nothing changes.
TEST(StructureAnchor, OrientByConsensusTurnsTheVoOrientationAndKeepsTheCentre) {
  const EnuFrame map_frame(Geodetic{49.0, 8.4, 115.0});
  Drive drive;
  const std::vector<size_t> indices = {0, 1, 2, 3};
  const std::vector<int> pose_of = {0, -1, 1, 2};  // drive frame 1 has no VO pose
  VoStructure vo;
  for (int i = 0; i < 3; ++i) {
    StampedPose p;
    p.timestamp_s = i;
    p.world_from_cam.rotation =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * (i + 1), Eigen::Vector3d(1, 2, 3).normalized()));
    p.world_from_cam.translation = Eigen::Vector3d(0.0, 0.0, 5.0 * i);
    vo.poses.push_back(p);
  }
  const structure_internal::MapLoader load;
  const StructureAnchorOptions options;
  const structure_internal::DriveAnchoring run{drive, indices,   pose_of, vo,
                                               load,  map_frame, options};
  AnchorDriveResult out;
  for (int k = 0; k < 4; ++k) {
    AnchorResult a;
    a.frame = k;
    a.has_pose = k != 1;
    a.map_from_cam.rotation =
        Eigen::Quaterniond(Eigen::AngleAxisd(-0.2 * k, Eigen::Vector3d::UnitZ()));
    structure_internal::SetCentre(map_frame, Eigen::Vector3d(300.0 * k, -200.0 * k, 2.0), &a);
    out.frames.push_back(a);
  }
  const AnchorDriveResult before = out;
  const Eigen::Quaterniond turn(
      Eigen::AngleAxisd(1.3, Eigen::Vector3d(0.2, -0.1, 1.0).normalized()));
  structure_internal::OrientByConsensus(run, {}, &out);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_LT(
        out.frames[k].map_from_cam.rotation.angularDistance(before.frames[k].map_from_cam.rotation),
        1e-15);
  }
  structure_internal::OrientByConsensus(run, {turn, turn, turn, std::nullopt}, &out);
  for (const size_t k : {size_t{0}, size_t{2}}) {
    const AnchorResult& a = out.frames[k];
    const Eigen::Quaterniond expected =
        turn * vo.poses[static_cast<size_t>(pose_of[k])].world_from_cam.rotation;
    EXPECT_LT(a.map_from_cam.rotation.angularDistance(expected), 1e-12) << k;
    EXPECT_LT((a.map_from_cam.translation - before.frames[k].map_from_cam.translation).norm(),
              1e-12);
    EXPECT_NEAR(a.position.lat_deg, before.frames[k].position.lat_deg, 1e-12);
    EXPECT_NEAR(a.position.lon_deg, before.frames[k].position.lon_deg, 1e-12);
    // ENU at the camera: the map frame's rotation seen from the local ENU there (off by the
    // meridian convergence 600 m east of the origin).
    const Eigen::Matrix3d enu =
        map_frame.EnuFromLocalEnu(a.position).transpose() * expected.toRotationMatrix();
    EXPECT_LT(a.enu_from_cam.angularDistance(Eigen::Quaterniond(enu)), 1e-12) << k;
    if (k == 2) {
      EXPECT_GT(a.enu_from_cam.angularDistance(expected), 1e-6);
    }
  }
  // No pose (frame 1) and no orientation (frame 3): unchanged.
  for (const size_t k : {size_t{1}, size_t{3}}) {
    EXPECT_LT(
        out.frames[k].map_from_cam.rotation.angularDistance(before.frames[k].map_from_cam.rotation),
        1e-15);
    EXPECT_LT(out.frames[k].enu_from_cam.angularDistance(before.frames[k].enu_from_cam), 1e-15);
  }
  EXPECT_THROW(structure_internal::OrientByConsensus(run, {turn}, &out), Error);
}

}  // namespace
}  // namespace epiloc
