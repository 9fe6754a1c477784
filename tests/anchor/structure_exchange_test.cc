// The fits' exchange (StructureAnchorOptions::exchange_rounds) on an exact street: facades set
// back in blocks of random length and depth, a ground plane, a VO that is the truth at half
// scale and a GNSS track on the cameras.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "epiloc/anchor/structure_anchor.h"
#include "structure_anchor_internal.h"
#include "test_util.h"

namespace epiloc {
namespace {

constexpr double kVoScale = 2.0;  // metres per VO unit

// The street: the road along +y (north), cameras 1.5 m high at x = +1.5, one per metre (frames
// 0..80, 10 Hz), looking along +y; facades 6 m either side of the road's middle, each set back by
// 0, 0.6, 1.2 or 1.8 m in blocks 3-7 m long (with the walls across at the steps), 8 m high.
struct SteppedStreet {
  static constexpr int kCameras = 81;
  Drive drive;
  std::vector<size_t> indices;
  std::vector<int> pose_of;
  VoStructure vo;
  PointCloud map;
  EnuFrame map_frame{Geodetic{49.0, 8.4, 110.0}};
  StructureAnchorOptions options;

  // One side's facade: the blocks' ends along y and their setbacks.
  struct Facade {
    std::vector<double> ends;
    std::vector<double> setbacks;
  };

  SteppedStreet() {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double y_lo = -40.0, y_hi = kCameras + 40.0;
    std::vector<Facade> facades(2);
    for (Facade& f : facades) {
      for (double y = y_lo; y < y_hi;) {
        y += 3.0 + 4.0 * u(rng);
        f.ends.push_back(y);
        f.setbacks.push_back(0.6 * std::floor(4.0 * u(rng)));
      }
    }
    // The surfaces as (point at parameters u, v in [0, 1]) with their areas.
    struct Patch {
      Eigen::Vector3d origin, du, dv;
    };
    std::vector<Patch> patches;
    patches.push_back({{-6.0, y_lo, 0.0}, {12.0, 0.0, 0.0}, {0.0, y_hi - y_lo, 0.0}});  // ground
    for (int side = 0; side < 2; ++side) {
      const Facade& f = facades[static_cast<size_t>(side)];
      const double sign = side == 0 ? -1.0 : 1.0;
      double start = y_lo;
      for (size_t b = 0; b < f.ends.size(); ++b) {
        const double x = sign * (6.0 + f.setbacks[b]);
        patches.push_back({{x, start, 0.0}, {0.0, f.ends[b] - start, 0.0}, {0.0, 0.0, 8.0}});
        if (b + 1 < f.ends.size() && f.setbacks[b + 1] != f.setbacks[b]) {
          const double x_next = sign * (6.0 + f.setbacks[b + 1]);
          patches.push_back({{x, f.ends[b], 0.0}, {x_next - x, 0.0, 0.0}, {0.0, 0.0, 8.0}});
        }
        start = f.ends[b];
      }
    }
    // The map: every patch every 0.2 m.
    for (const Patch& p : patches) {
      const int nu = std::max(1, static_cast<int>(std::ceil(p.du.norm() / 0.2)));
      const int nv = std::max(1, static_cast<int>(std::ceil(p.dv.norm() / 0.2)));
      for (int i = 0; i <= nu; ++i) {
        for (int j = 0; j <= nv; ++j) {
          const Eigen::Vector3d x = p.origin + p.du * i / nu + p.dv * j / nv;
          map.positions.push_back(x.cast<float>());
        }
      }
    }
    // The cameras, the VO (the truth at 1 / kVoScale) and the GNSS on the cameras.
    Eigen::Matrix3d map_from_cam;  // x right, y down, z forward
    map_from_cam << 1, 0, 0,       //
        0, 0, 1,                   //
        0, -1, 0;
    drive.max_gap_s = 0.5;
    for (int i = 0; i < kCameras; ++i) {
      const Eigen::Vector3d centre(1.5, i, 1.5);
      FrameRecord record;
      record.frame = i;
      record.timestamp_s = 0.1 * i;
      drive.frames.push_back(record);
      PositionSample gnss;
      gnss.timestamp_s = record.timestamp_s;
      gnss.position = map_frame.ToGeodetic(centre);
      drive.gnss.samples.push_back(gnss);
      StampedPose pose;
      pose.frame = i;
      pose.timestamp_s = record.timestamp_s;
      pose.world_from_cam = Rigid3d(Eigen::Quaterniond(map_from_cam), centre / kVoScale);
      vo.poses.push_back(pose);
      pose_of.push_back(i);
    }
    // The VO's points: on the surfaces at random (by area), seen by the cameras 1-35 m behind.
    std::vector<double> area;
    for (const Patch& p : patches) {
      area.push_back((area.empty() ? 0.0 : area.back()) + p.du.norm() * p.dv.norm());
    }
    for (int n = 0; n < 12000; ++n) {
      const double pick = area.back() * u(rng);
      const size_t at =
          static_cast<size_t>(std::lower_bound(area.begin(), area.end(), pick) - area.begin());
      const Patch& p = patches[std::min(at, patches.size() - 1)];
      const Eigen::Vector3d x = p.origin + p.du * u(rng) + p.dv * u(rng);
      const int first = std::max(0, static_cast<int>(std::ceil(x.y() - 35.0)));
      const int last = std::min(kCameras - 1, static_cast<int>(std::floor(x.y() - 1.0)));
      if (last - first + 1 < 3) continue;
      VoPoint point;
      point.point_in_world = x / kVoScale;
      point.first_frame = first;
      point.last_frame = last;
      point.observations = last - first + 1;
      point.parallax_deg = NAN;
      vo.points.push_back(point);
    }
    for (int f = 10; f <= 70; f += 5) indices.push_back(static_cast<size_t>(f));
    options.map_voxel_m = 0.0;
    options.prior.camera_height_m = 1.5;
    options.registration.search_step_m = 0.0;  // from the (exact) GNSS seed alone
    options.num_threads = 2;
  }

  structure_internal::MapLoader Loader() const {
    return [this](const Eigen::Vector3d&, double) { return map; };
  }
};

// The map similarity of the truth: the VO world at kVoScale.
Similarity3 TrueSimilarity() {
  Similarity3 s;
  s.scale = kVoScale;
  return s;
}

// Two anchors whose fits sit 4 m ahead along the road (one iteration from there at the finest
// level: the facades hold a structure moved along them, with fewer of its points on the map) are
// registered again from their better-fitting neighbours' fits and keep those: back on the truth.
// The others, whose neighbours fit no better, keep their fits as they were. No rounds: nothing
// changes.
TEST(StructureExchange, AnchorsInAnotherBasinTakeTheirBetterFittingNeighboursFit) {
  SteppedStreet street;
  const structure_internal::MapLoader load = street.Loader();
  const structure_internal::DriveAnchoring run{street.drive,  street.indices, street.pose_of,
                                               street.vo,     load,           street.map_frame,
                                               street.options};
  AnchorDriveResult first;
  first.frames.resize(street.indices.size());
  for (size_t k = 0; k < street.indices.size(); ++k) {
    first.frames[k] = structure_internal::AnchorOne(run, street.indices[k]);
    ASSERT_TRUE(first.frames[k].has_pose) << k;
    const Eigen::Vector3d truth(1.5, static_cast<double>(street.indices[k]), 1.5);
    ASSERT_LT((first.frames[k].map_from_cam.translation - truth).norm(), 0.01) << k;
  }
  // The stuck fits: one iteration at the finest level from 4 m ahead, no profile moves (the
  // street's steps pull a full registration back).
  StructureAnchorOptions one_step = street.options;
  one_step.registration.max_iterations_per_level = 1;
  one_step.registration.profile_moves = 0;
  const structure_internal::DriveAnchoring stick{
      street.drive, street.indices, street.pose_of, street.vo, load, street.map_frame, one_step};
  const std::vector<size_t> moved = {4, 5};  // frames 30 and 35
  AnchorDriveResult stuck = first;
  for (const size_t k : moved) {
    structure_internal::Restart ahead;
    ahead.sim = TrueSimilarity();
    ahead.sim.translation = Eigen::Vector3d(0.0, 4.0, 0.0);
    ahead.levels_m = {0.3};
    stuck.frames[k] = structure_internal::AnchorOne(stick, street.indices[k], &ahead);
    ASSERT_TRUE(stuck.frames[k].has_pose);
    const double off = stuck.frames[k].map_from_cam.translation.y() - street.indices[k];
    ASSERT_GT(off, 3.0) << k;  // still in the basin 4 m ahead
    ASSERT_LT(stuck.frames[k].num_inliers, first.frames[k].num_inliers) << k;
  }

  AnchorDriveResult exchanged = stuck;
  structure_internal::ExchangeFits(run, &exchanged);
  for (size_t k = 0; k < street.indices.size(); ++k) {
    const AnchorResult& a = exchanged.frames[k];
    const Eigen::Vector3d truth(1.5, static_cast<double>(street.indices[k]), 1.5);
    EXPECT_LT((a.map_from_cam.translation - truth).norm(), 0.01) << k;
    if (k == moved[0] || k == moved[1]) {
      EXPECT_NE(a.message.find("registered from frame"), std::string::npos) << a.message;
      EXPECT_GE(a.num_inliers, first.frames[k].num_inliers - 5) << k;
    } else {
      EXPECT_EQ(a.map_from_cam.translation, stuck.frames[k].map_from_cam.translation) << k;
      EXPECT_TRUE(a.message.empty()) << a.message;
    }
  }

  street.options.exchange_rounds = 0;
  const structure_internal::DriveAnchoring off{street.drive,  street.indices, street.pose_of,
                                               street.vo,     load,           street.map_frame,
                                               street.options};
  AnchorDriveResult unchanged = stuck;
  structure_internal::ExchangeFits(off, &unchanged);
  for (const size_t k : moved) {
    EXPECT_EQ(unchanged.frames[k].map_from_cam.translation,
              stuck.frames[k].map_from_cam.translation);
  }
}

}  // namespace
}  // namespace epiloc
