// What a map can give structure anchoring (`epiloc anchor --vo`, issue 17), measured with exact
// structure: the 3-D points of a route database triangulated from its survey's true poses
// (`epiloc build-db` + `epiloc triangulate` on a drive with ground truth) registered to a LiDAR
// map by the same Sim(3) ICP the anchors use. Prints figures; not a test.
//
// Exact structure has no VO error, no scale drift and no seed error, so what is left is the map:
// (1) the whole drive's points, fitted from the truth by the fine levels alone: the offset between
//     the map and the survey's ground truth (no anchor measured in the map can be graded nearer
//     the truth than this);
// (2) per window of frames about every `--every`-th frame (the anchors' window): the fit from the
//     truth with the anchors' whole schedule and seed search, and from seeds 1 m off along and
//     across the road, and the seed search followed by the fine levels alone: how far the
//     registration lands from the truth when nothing else is wrong.
// (3) with --grid: how many points lie within 0.1 m of the map's surface (the finest level's loss
//     scale) over a grid of horizontal moves from the truth, for the whole drive and each window,
//     and for each window the same counting only points whose map surface is a plane facing along
//     the road (the only points that measure along it): where the map itself puts the structure,
//     no optimiser involved.
// (4) with --depth: where the map's surface is a plane facing the camera, how far beyond the
//     structure point it lies along the viewing ray, by depth: a structure triangulated along a
//     track that is too short (or too long) lies nearer (farther) than the LiDAR's surfaces.
//
// Usage: epiloc_bench_structure_bound --db route.sqlite --cloud map.ply
//        [--cloud-origin LAT,LON,ALT] [--voxel 0.2] [--half-window 20] [--every 20] [--range 35]
//        [--min-observations 3] [--grid] [--depth]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>

#include "epiloc/anchor/map_sidecar.h"
#include "epiloc/anchor/structure_registration.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/voxel.h"
#include "epiloc/core/error.h"
#include "epiloc/db/database.h"
#include "epiloc/geo/geodetic.h"

namespace epiloc {
namespace {

struct Offset {
  double along = 0, across = 0, up = 0, rotation_deg = 0, scale = 1;
  double yaw_deg = 0, about_left_deg = 0, about_forward_deg = 0;  // the turn's rotation vector
};

// How far `s` moves the point `at` (metres, split along / across the horizontal `forward` and
// up) and how much it turns.
Offset OffsetAt(const Similarity3& s, const Eigen::Vector3d& at, const Eigen::Vector3d& forward) {
  const Eigen::Vector3d d = s * at - at;
  const Eigen::Vector3d left = Eigen::Vector3d::UnitZ().cross(forward);
  const Eigen::AngleAxisd turn(s.rotation);
  const Eigen::Vector3d v = turn.angle() * 180.0 / M_PI * turn.axis();
  return {d.dot(forward), d.dot(left), d.z(),       turn.angle() * 180.0 / M_PI,
          s.scale,        v.z(),       v.dot(left), v.dot(forward)};
}

// Whether the map's surface at a point (its projector, StructureMap::Projector) is a plane whose
// normal lies within 45 degrees of `direction` (unit): a plane's projector is n n^T (trace 1;
// a line's has trace 2, a point's 3), and (n . d)^2 = d^T P d.
bool PlaneFacing(const Eigen::Matrix3d& projector, const Eigen::Vector3d& direction) {
  return std::abs(projector.trace() - 1.0) <= 1e-3 && direction.dot(projector * direction) >= 0.5;
}

void Print(const char* label, const StructureRegistration& r, const Offset& o) {
  std::printf(
      "  %-22s along %+6.2f across %+6.2f up %+6.2f m, rot %5.2f deg (yaw %+.2f, about left "
      "%+.2f, about forward %+.2f), scale %.3f; inliers %.2f, along_sigma %.2f m%s\n",
      label, o.along, o.across, o.up, o.rotation_deg, o.yaw_deg, o.about_left_deg,
      o.about_forward_deg, o.scale, r.inlier_share, r.along_sigma_m, r.success ? "" : " (failed)");
}

int Run(int argc, char** argv) {
  CLI::App app{"Structure anchoring's bound: exact survey structure registered to a LiDAR map"};
  std::string db_path, cloud_path, cloud_origin;
  int half_window = 20, every = 20, min_observations = 3;
  double range_m = 35.0;
  bool with_grid = false;
  app.add_option("--db", db_path, "Route database with triangulated points (true poses)")
      ->required();
  app.add_option("--cloud", cloud_path, "LiDAR map with its origin sidecar")->required();
  app.add_option("--cloud-origin", cloud_origin,
                 "LAT,LON,ALT of the cloud's ENU origin (default: its sidecar's; a synthetic "
                 "world's: 49,8.4,115)");
  app.add_option("--half-window", half_window, "Frames either side of a window's centre");
  app.add_option("--every", every, "Window centres every this many frames");
  double voxel_m = 0.2;
  app.add_option("--voxel", voxel_m, "Map voxel side, metres (0: none; `anchor` uses 0.2)");
  bool with_depth = false;
  app.add_flag("--depth", with_depth,
               "Also the offset of the map's surfaces facing the camera from the structure, by "
               "depth (a structure biased in depth, or a map shifted along the road)");
  app.add_option("--range", range_m, "Points within this of the centre camera, metres");
  app.add_option("--min-observations", min_observations,
                 "Points seen by at least this many frames");
  app.add_flag("--grid", with_grid,
               "Also count the points on the map's surfaces over a grid of moves from the truth");
  CLI11_PARSE(app, argc, argv);

  Database db(db_path, Database::Mode::kReadOnly);
  const std::optional<Geodetic> db_origin = db.EnuOrigin();
  if (!db_origin) Throw("{}: no ENU origin", db_path);
  // The map in the database's ENU frame (origins metres apart: a translation).
  const std::optional<MapSidecar> sidecar = FindMapSidecar(cloud_path);
  if (!sidecar && cloud_origin.empty())
    Throw("{}: no origin sidecar; give --cloud-origin", cloud_path);
  const Geodetic map_origin =
      cloud_origin.empty() ? sidecar->enu_origin : ParseGeodetic(cloud_origin, "--cloud-origin");
  const Eigen::Vector3f map_in_db = EnuFrame(*db_origin).ToEnu(map_origin).cast<float>();
  PointCloud cloud = ReadPointCloud(cloud_path);
  if (voxel_m > 0) cloud = VoxelFilter(cloud, voxel_m);
  for (Eigen::Vector3f& p : cloud.positions) p += map_in_db;
  cloud.intensity.clear();
  cloud.rgb.clear();
  StructureRegistrationOptions options;
  StructureMap map(cloud, options);

  // Frames and the points each sees.
  const std::vector<DbFrame> frames = db.ReadFrames();
  std::map<int64_t, Eigen::Vector3d> points;
  std::map<int64_t, int> observations;
  std::vector<std::vector<int64_t>> seen(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    for (const DbFramePoint& p : db.ReadFramePoints(frames[i].image_id)) {
      points[p.point_id] = p.position_in_enu;
      ++observations[p.point_id];
      seen[i].push_back(p.point_id);
    }
  }
  std::printf(
      "%s: %zu frames, %zu points; map %zu points (%.2f m voxels), %+.3f %+.3f %+.3f m "
      "from the database's origin\n",
      db_path.c_str(), frames.size(), points.size(), map.size(), voxel_m, map_in_db.x(),
      map_in_db.y(), map_in_db.z());

  // (4) Depth: each point seen from its nearest observing camera; where the map's surface there
  // is a plane facing that camera (normal within 45 deg of the viewing ray), the point's signed
  // distance to it along the ray (positive: the map's surface lies beyond the point). A structure
  // triangulated too near (or a map shifted away) shows a positive median growing with depth
  // (or not).
  if (with_depth) {
    std::map<int64_t, std::pair<double, size_t>> nearest_camera;  // point -> (distance, frame)
    for (size_t i = 0; i < frames.size(); ++i) {
      for (int64_t id : seen[i]) {
        const double d = (points[id] - frames[i].center_in_enu).norm();
        auto it = nearest_camera.find(id);
        if (it == nearest_camera.end() || d < it->second.first) nearest_camera[id] = {d, i};
      }
    }
    const std::vector<double> edges = {0, 5, 8, 12, 16, 20, 25, 35, 60};
    std::vector<std::vector<double>> along_ray(edges.size() - 1);
    for (const auto& [id, at] : nearest_camera) {
      if (observations[id] < min_observations) continue;
      const Eigen::Vector3d& x = points[id];
      const Eigen::Vector3d ray = (x - frames[at.second].center_in_enu).normalized();
      const int n = map.Nearest(x, 1.0);
      if (n < 0) continue;
      const Eigen::Matrix3d proj = map.Projector(n).cast<double>();
      if (!PlaneFacing(proj, ray)) continue;
      // Along the ray to the plane: n (n . (q - x)) = P (q - x), and n (n . ray) = P ray.
      const double t = ray.dot(proj * (map.Point(n).cast<double>() - x)) / ray.dot(proj * ray);
      if (std::abs(t) > 1.0) continue;
      for (size_t b = 0; b + 1 < edges.size(); ++b) {
        if (at.first >= edges[b] && at.first < edges[b + 1]) along_ray[b].push_back(t);
      }
    }
    std::printf(
        "offset of the map's facing surface from the structure along the viewing ray "
        "(positive: beyond), by depth:\n");
    for (size_t b = 0; b + 1 < edges.size(); ++b) {
      std::vector<double>& v = along_ray[b];
      if (v.empty()) continue;
      std::sort(v.begin(), v.end());
      std::printf(
          "  %4.0f-%-4.0f m: %6zu points, median %+.3f m, quartiles %+.3f %+.3f (%+.2f %% of "
          "depth)\n",
          edges[b], edges[b + 1], v.size(), v[v.size() / 2], v[v.size() / 4], v[3 * v.size() / 4],
          100.0 * v[v.size() / 2] / (0.5 * (edges[b] + edges[b + 1])));
    }
  }

  // (1) The whole drive: fine levels from the truth, the anchor's schedule and its parts.
  StructureRegistrationOptions fine = options;
  fine.max_distances_m = {0.6, 0.4, 0.25};
  fine.search_step_m = 0;
  std::vector<Eigen::Vector3d> all;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& [id, x] : points) {
    if (observations[id] < min_observations) continue;
    all.push_back(x);
    centroid += x;
  }
  centroid /= std::max<size_t>(all.size(), 1);
  const auto whole = [&](const char* label, const Eigen::Vector3d& seed_move,
                         const StructureRegistrationOptions& o) {
    Similarity3 seed;
    seed.translation = seed_move;
    const StructureRegistration r = RegisterStructure(all, map, seed, Eigen::Vector3d::UnitY(), o);
    const Eigen::Vector3d d = r.map_from_world * centroid - centroid;
    std::printf(
        "whole drive (%zu points), %s: the structure moves east %+.3f north %+.3f up "
        "%+.3f m (horizontal %.3f), turns %.3f deg, scale %.4f; inliers %.2f\n",
        all.size(), label, d.x(), d.y(), d.z(), d.head<2>().norm(),
        Eigen::AngleAxisd(r.map_from_world.rotation).angle() * 180.0 / M_PI, r.map_from_world.scale,
        r.inlier_share);
  };
  whole("fine levels from the truth", Eigen::Vector3d::Zero(), fine);
  whole("anchor's schedule from the truth", Eigen::Vector3d::Zero(), options);
  {
    StructureRegistrationOptions o = options;
    o.search_step_m = 0;
    whole("anchor's levels, no search, from the truth", Eigen::Vector3d::Zero(), o);
    o = fine;
    o.search_step_m = options.search_step_m;
    whole("search + fine levels, from the truth", Eigen::Vector3d::Zero(), o);
  }
  whole("anchor's schedule from 3 m east", Eigen::Vector3d(3, 0, 0), options);
  whole("anchor's schedule from 3 m north", Eigen::Vector3d(0, 3, 0), options);

  // The count of points on the map's surfaces over a grid of horizontal moves from the truth.
  const auto grid = [&](const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& fwd,
                        double tol, bool facing) {
    const Eigen::Vector3d lft = Eigen::Vector3d::UnitZ().cross(fwd);
    std::printf(
        "  points within %.2f m of the map's surface%s, moved along (rows) and across "
        "(columns, left positive):\n",
        tol, facing ? " where it is a plane facing along the road" : "");
    int best = -1;
    double ba = 0, bc = 0;
    for (double a = -2.0; a <= 2.01; a += 0.25) {
      std::printf("  %+5.2f:", a);
      for (double c = -1.0; c <= 1.01; c += 0.25) {
        int count = 0;
        for (const Eigen::Vector3d& p : pts) {
          const Eigen::Vector3d x = p + a * fwd + c * lft;
          const int n = map.Nearest(x, 0.5);
          if (n < 0) continue;
          const Eigen::Matrix3d proj = map.Projector(n).cast<double>();
          if (facing && !PlaneFacing(proj, fwd)) continue;
          const double d = (proj * (x - map.Point(n).cast<double>())).norm();
          count += d < tol;
        }
        std::printf(" %6d", count);
        if (count > best) {
          best = count;
          ba = a;
          bc = c;
        }
      }
      std::printf("\n");
    }
    std::printf("  best at along %+.2f across %+.2f: %d\n", ba, bc, best);
  };
  if (with_grid) {
    std::printf("whole drive, moves east (rows) and north (columns):\n");
    grid(all, Eigen::Vector3d::UnitX(), 0.1, false);
  }

  // (2) Windows.
  std::vector<double> from_truth, from_off, search_fine_truth, search_fine_off;
  StructureRegistrationOptions search_fine = fine;
  search_fine.search_step_m = options.search_step_m;
  for (size_t c = 0; c < frames.size(); c += every) {
    const Eigen::Vector3d centre = frames[c].center_in_enu;
    const double heading = frames[c].heading_deg * M_PI / 180.0;
    const Eigen::Vector3d forward(std::sin(heading), std::cos(heading), 0.0);
    const Eigen::Vector3d left = Eigen::Vector3d::UnitZ().cross(forward);
    std::vector<int64_t> ids;
    for (size_t i = c >= static_cast<size_t>(half_window) ? c - half_window : 0;
         i < std::min(frames.size(), c + half_window + 1); ++i) {
      ids.insert(ids.end(), seen[i].begin(), seen[i].end());
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    std::vector<Eigen::Vector3d> window;
    for (int64_t id : ids) {
      const Eigen::Vector3d& x = points[id];
      if (observations[id] >= min_observations && (x - centre).norm() <= range_m) {
        window.push_back(x);
      }
    }
    std::printf("frame %lld (%zu points):\n", static_cast<long long>(frames[c].frame),
                window.size());
    if (with_grid) {
      grid(window, forward, 0.1, false);
      grid(window, forward, 0.1, true);
    }
    const auto run = [&](const char* label, const Eigen::Vector3d& seed_move,
                         const StructureRegistrationOptions& o, std::vector<double>* errors) {
      Similarity3 seed;
      seed.translation = seed_move;
      const StructureRegistration r = RegisterStructure(window, map, seed, forward, o);
      const Offset off = OffsetAt(r.map_from_world, centre, forward);
      Print(label, r, off);
      if (errors) errors->push_back(std::hypot(off.along, off.across));
    };
    run("fine, from the truth", Eigen::Vector3d::Zero(), fine, nullptr);
    run("fine, 0.5 m ahead", 0.5 * forward, fine, nullptr);
    run("fine, 1 m ahead", forward, fine, nullptr);
    run("fine, 1 m right", -left, fine, nullptr);
    run("anchor's, from truth", Eigen::Vector3d::Zero(), options, &from_truth);
    run("anchor's, 1 m ahead", forward, options, &from_off);
    run("anchor's, 1 m behind", -forward, options, &from_off);
    run("anchor's, 1 m left", left, options, &from_off);
    run("anchor's, 1 m right", -left, options, &from_off);
    run("search + fine, truth", Eigen::Vector3d::Zero(), search_fine, &search_fine_truth);
    run("search + fine, 2 m ahead", 2 * forward, search_fine, &search_fine_off);
    run("search + fine, 3 m left", 3 * left, search_fine, &search_fine_off);
  }
  const auto summary = [](const char* label, std::vector<double> v) {
    if (v.empty()) return;
    std::sort(v.begin(), v.end());
    std::printf("%s: horizontal median %.2f m, max %.2f m (%zu fits)\n", label, v[v.size() / 2],
                v.back(), v.size());
  };
  summary("windows, anchor's schedule from the truth", from_truth);
  summary("windows, anchor's schedule from 1 m off", from_off);
  summary("windows, search + fine levels from the truth", search_fine_truth);
  summary("windows, search + fine levels from 2-3 m off", search_fine_off);
  return 0;
}

}  // namespace
}  // namespace epiloc

int main(int argc, char** argv) {
  try {
    return epiloc::Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "epiloc_bench_structure_bound: error: %s\n", e.what());
    return 1;
  }
}
