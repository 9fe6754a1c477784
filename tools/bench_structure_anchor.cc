// Diagnosis of structure anchoring (`epiloc anchor --vo`, issue 17) on the anchor tests'
// synthetic street (prints figures; not a test): the query's VO against the ground truth, its
// points against the world's surfaces and the LiDAR map under the true similarity, the ICP from
// the true similarity, and the along-track profile of points on the map (the simulated map, the
// world's exact surfaces, a dense 360-degree LiDAR). README "Anchoring from structure".
#include <algorithm>
#include <cstdio>

#include <Eigen/SVD>

#include "anchor_test_util.h"
#include "epiloc/anchor/structure_anchor.h"
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/voxel.h"
#include "epiloc/synth/lidar.h"
#include "epiloc/synth/world.h"

namespace epiloc {
namespace {

double Pct(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
}

struct Frame {
  Rigid3d vo;     // world_from_cam
  Rigid3d truth;  // map_from_cam
};

Similarity3 FitTrue(const std::vector<Frame>& frames) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (const Frame& f : frames)
    sum += f.truth.rotation.toRotationMatrix() * f.vo.rotation.conjugate().toRotationMatrix();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
    d(2, 2) = -1;
    r = svd.matrixU() * d * svd.matrixV().transpose();
  }
  Eigen::Vector3d mv = Eigen::Vector3d::Zero(), mt = Eigen::Vector3d::Zero();
  for (const Frame& f : frames) {
    mv += f.vo.translation;
    mt += f.truth.translation;
  }
  mv /= frames.size();
  mt /= frames.size();
  double num = 0, den = 0;
  for (const Frame& f : frames) {
    const Eigen::Vector3d a = r * (f.vo.translation - mv);
    num += a.dot(f.truth.translation - mt);
    den += a.squaredNorm();
  }
  Similarity3 s;
  s.scale = num / den;
  s.rotation = Eigen::Quaterniond(r);
  s.translation = mt - s.scale * (r * mv);
  return s;
}

// The along-track profile of a registration: for shifts of -2..2 m along the route from the
// true similarity, how many points lie within 0.1 m of the map's local plane (and a map point
// within 0.4 m), and how many within 0.2 m. Prints " shift:count/count" on one line.
void PrintShiftProfile(const std::vector<Eigen::Vector3d>& points,
                       StructureMap& map,
                       const Similarity3& s_true,
                       const Eigen::Vector3d& along) {
  for (double a = -2.0; a <= 2.01; a += 0.2) {
    Similarity3 s = s_true;
    s.translation += a * along;
    int c1 = 0, c2 = 0;
    for (const Eigen::Vector3d& p : points) {
      const Eigen::Vector3d x = s * p;
      const int n = map.Nearest(x, 0.4);
      if (n < 0) continue;
      const double d = (map.Projector(n).cast<double>() * (x - map.Point(n).cast<double>())).norm();
      c1 += d < 0.1;
      c2 += d < 0.2;
    }
    std::printf(" %+.1f:%d/%d", a, c1, c2);
  }
  std::printf("\n");
}

void Report(const char* label, const Similarity3& s, const std::vector<Frame>& frames) {
  std::vector<double> h, rot;
  double al = 0, ac = 0, up = 0, yaw = 0, tilt = 0;
  for (const Frame& f : frames) {
    const Eigen::Vector3d d = s * f.vo.translation - f.truth.translation;
    Eigen::Vector3d fw = f.truth.rotation * Eigen::Vector3d::UnitZ();
    fw.z() = 0;
    fw.normalize();
    al += d.dot(fw) / frames.size();
    ac += d.dot(Eigen::Vector3d::UnitZ().cross(fw)) / frames.size();
    up += d.z() / frames.size();
    h.push_back((s * f.vo.translation - f.truth.translation).head<2>().norm());
    rot.push_back(RotationDifferenceDeg(s.rotation * f.vo.rotation, f.truth.rotation));
    // The error rotation in the map: its vertical part is a turn (yaw), the rest a tilt.
    const Eigen::AngleAxisd e(s.rotation * f.vo.rotation * f.truth.rotation.conjugate());
    yaw += e.angle() * e.axis().z() * 180.0 / M_PI / frames.size();
    tilt += e.angle() * e.axis().head<2>().norm() * 180.0 / M_PI / frames.size();
  }
  std::printf("%-40s mean along %+.3f across %+.3f up %+.3f, yaw %+.2f tilt %.2f deg; ", label, al,
              ac, up, yaw, tilt);
  std::printf("%-4s scale %.4f  horiz median %.3f max %.3f m, rot median %.3f max %.3f deg\n", "",
              s.scale, Pct(h, 0.5), Pct(h, 1.0), Pct(rot, 0.5), Pct(rot, 1.0));
}

void Run() {
  const std::string world_dir = SharedSyntheticWorld();
  const Drive query = LoadDrive(world_dir + "/query");
  const VoResult vr = RunVisualOdometry(query, VoOptions());
  const VoStructure vo = VoStructure::FromResult(vr);
  const EnuFrame enu(SynthOrigin());
  std::vector<Frame> frames;
  for (const StampedPose& p : vo.poses) {
    const auto t = TrueMapFromCam(query, p.timestamp_s, enu);
    if (t) frames.push_back({p.world_from_cam, *t});
  }
  std::printf("%zu VO poses, %zu points, %zu segments\n", frames.size(), vo.points.size(),
              vo.segments.size());
  const Similarity3 s_true = FitTrue(frames);
  Report("true similarity (all frames)", s_true, frames);
  // Scale along the drive: truth distance / VO distance over 3-frame steps.
  std::printf("local scale (truth m per VO unit) over 3 frames:");
  for (size_t i = 0; i + 3 < frames.size(); i += 3) {
    std::printf(" %.3f", (frames[i + 3].truth.translation - frames[i].truth.translation).norm() /
                             (frames[i + 3].vo.translation - frames[i].vo.translation).norm());
  }
  std::printf("\n");

  // World surfaces.
  SynthOptions so;
  so.length_m = 50.0;
  so.seed = 3;
  const World world = BuildWorld(so.ResolvedWorldOptions());
  const auto surface_distance = [&](const Eigen::Vector3d& x, int* kind) {
    double best = INFINITY;
    for (const Surface& s : world.surfaces) {
      if (s.texture < 0) continue;
      const double d = std::abs(s.Normal().dot(x) - s.PlaneOffset());
      if (d < best && s.Contains(x, 0.3)) {
        best = d;
        *kind = static_cast<int>(s.kind);
      }
    }
    return best;
  };
  PointCloud map = VoxelFilter(ReadPointCloud(world_dir + "/lidar/map.ply"), 0.2);
  map.intensity.clear();
  map.rgb.clear();
  StructureRegistrationOptions ro;
  StructureMap smap(map, ro);
  std::vector<Eigen::Vector3d> points;
  for (const VoPoint& p : vo.points)
    if (p.observations >= 3) points.push_back(p.point_in_world);
  std::vector<double> dsurf, dmap;
  int kinds[16] = {0}, kinds_unmapped[16] = {0};
  std::vector<double> z_unmapped, z_mapped, range_unmapped;
  int near_surface_no_map = 0, far_surface = 0;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d x = s_true * p;
    int kind = -1;
    const double ds = surface_distance(x, &kind);
    dsurf.push_back(ds);
    const int n = smap.Nearest(x, 5.0);
    const double dm =
        n < 0 ? 5.0
              : (smap.Projector(n).cast<double>() * (x - smap.Point(n).cast<double>())).norm();
    const double dpt = n < 0 ? 5.0 : (x - smap.Point(n).cast<double>()).norm();
    dmap.push_back(dm);
    if (kind >= 0) ++kinds[kind];
    if (ds > 0.3) ++far_surface;
    if (ds <= 0.3 && dpt > 0.3) {
      ++near_surface_no_map;
      if (kind >= 0) ++kinds_unmapped[kind];
      z_unmapped.push_back(x.z());
    } else if (dpt <= 0.3) {
      z_mapped.push_back(x.z());
    }
  }
  {
    // Point error by parallax, observations and range.
    struct Bin {
      std::vector<double> d;
    };
    const double pb[] = {0, 2, 4, 8, 16, 1000};
    const int ob[] = {3, 4, 6, 10, 1000};
    const double rb[] = {0, 8, 15, 25, 1000};
    std::vector<double> bypar[5], byobs[4], byrange[4];
    for (const VoPoint& p : vo.points) {
      if (p.observations < 3) continue;
      int kind = -1;
      const Eigen::Vector3d x = s_true * p.point_in_world;
      const double ds = surface_distance(x, &kind);
      if (!std::isfinite(ds)) continue;
      double range = INFINITY;
      for (const Frame& f : frames) range = std::min(range, (x - f.truth.translation).norm());
      for (int i = 0; i < 5; ++i)
        if (p.parallax_deg >= pb[i] && p.parallax_deg < pb[i + 1]) bypar[i].push_back(ds);
      for (int i = 0; i < 4; ++i)
        if (p.observations >= ob[i] && p.observations < ob[i + 1]) byobs[i].push_back(ds);
      for (int i = 0; i < 4; ++i)
        if (range >= rb[i] && range < rb[i + 1]) byrange[i].push_back(ds);
    }
    for (int i = 0; i < 5; ++i)
      std::printf("  parallax [%g,%g) deg: %zu points, surface distance median %.3f p75 %.3f\n",
                  pb[i], pb[i + 1], bypar[i].size(), Pct(bypar[i], 0.5), Pct(bypar[i], 0.75));
    for (int i = 0; i < 4; ++i)
      std::printf("  observations [%d,%d): %zu points, median %.3f p75 %.3f\n", ob[i], ob[i + 1],
                  byobs[i].size(), Pct(byobs[i], 0.5), Pct(byobs[i], 0.75));
    for (int i = 0; i < 4; ++i)
      std::printf("  range [%g,%g) m: %zu points, median %.3f p75 %.3f\n", rb[i], rb[i + 1],
                  byrange[i].size(), Pct(byrange[i], 0.5), Pct(byrange[i], 0.75));
  }
  std::printf("%zu points (>=3 obs) under the true similarity:\n", points.size());
  std::printf(
      "  distance to the world's surfaces: p25 %.3f median %.3f p75 %.3f p90 %.3f m; "
      "> 0.3 m: %d\n",
      Pct(dsurf, 0.25), Pct(dsurf, 0.5), Pct(dsurf, 0.75), Pct(dsurf, 0.9), far_surface);
  std::printf("  point-to-plane distance to the map: p25 %.3f median %.3f p75 %.3f m\n",
              Pct(dmap, 0.25), Pct(dmap, 0.5), Pct(dmap, 0.75));
  std::printf(
      "  within 0.3 m of a surface but no map point within 0.3 m: %d (z median %.2f, "
      "p10 %.2f); mapped z median %.2f p90 %.2f\n",
      near_surface_no_map, Pct(z_unmapped, 0.5), Pct(z_unmapped, 0.1), Pct(z_mapped, 0.5),
      Pct(z_mapped, 0.9));
  for (int k = 0; k < 13; ++k)
    if (kinds[k])
      std::printf("  kind %-10s %4d points, %4d without map\n",
                  SurfaceKindName(static_cast<SurfaceKind>(k)), kinds[k], kinds_unmapped[k]);

  // ICP from the true similarity.
  const Eigen::Vector3d along =
      (frames.back().truth.translation - frames.front().truth.translation).normalized();
  StructureRegistrationOptions nos = ro;
  nos.search_step_m = 0.0;
  auto fit = RegisterStructure(points, smap, s_true, along, nos);
  std::printf("ICP from the truth (all levels): share %.2f rms %.3f\n", fit.inlier_share,
              fit.rms_m);
  Report("  result", fit.map_from_world, frames);
  StructureRegistrationOptions fine = nos;
  fine.max_distances_m = {0.6, 0.4, 0.25};
  fit = RegisterStructure(points, smap, s_true, along, fine);
  std::printf("ICP from the truth (0.6 0.4 0.25): share %.2f rms %.3f\n", fit.inlier_share,
              fit.rms_m);
  Report("  result", fit.map_from_world, frames);
  fit = RegisterStructure(points, smap, s_true, along, ro);
  std::printf("ICP from the truth with search: share %.2f rms %.3f moved %.2f %.2f yaw %.1f\n",
              fit.inlier_share, fit.rms_m, fit.search_offset_m.x(), fit.search_offset_m.y(),
              fit.search_yaw_deg);
  Report("  result", fit.map_from_world, frames);
  // Selections by predicted depth uncertainty (1 px over the focal length).
  const double fx = query.camera.fx;
  struct Sel {
    const char* name;
    double max_sigma_m;
  };
  for (const Sel sel : {Sel{"all", 1e9}, Sel{"sigma<=0.5", 0.5}, Sel{"sigma<=0.3", 0.3},
                        Sel{"sigma<=0.2", 0.2}, Sel{"sigma<=0.1", 0.1}}) {
    std::vector<Eigen::Vector3d> chosen;
    std::vector<double> dsel;
    for (const VoPoint& p : vo.points) {
      if (p.observations < 3) continue;
      double range = INFINITY;
      for (const Frame& f : frames)
        range = std::min(range, (p.point_in_world - f.vo.translation).norm());
      const double range_m = range * s_true.scale;
      const double sigma = range_m / fx / std::sin(std::max(p.parallax_deg, 0.1) * M_PI / 180);
      if (sigma > sel.max_sigma_m) continue;
      chosen.push_back(p.point_in_world);
      int kind;
      dsel.push_back(surface_distance(s_true * p.point_in_world, &kind));
    }
    const auto f0 = RegisterStructure(chosen, smap, s_true, along, fine);
    std::printf(
        "%-12s %4zu points, surface dist median %.3f p75 %.3f; fine ICP from truth share %.2f rms "
        "%.3f\n",
        sel.name, chosen.size(), Pct(dsel, 0.5), Pct(dsel, 0.75), f0.inlier_share, f0.rms_m);
    Report("   fine ICP from truth", f0.map_from_world, frames);
    const auto f1 = RegisterStructure(chosen, smap, s_true, along, nos);
    Report("   full ICP from truth", f1.map_from_world, frames);
    std::printf("   shift: count(plane<0.1 & point<0.4) / (plane<0.2):");
    PrintShiftProfile(chosen, smap, s_true, along);
  }
  {
    // The along-track profile against the world's exact surfaces (a perfect map).
    for (const double max_sigma : {1e9, 0.3}) {
      std::vector<Eigen::Vector3d> chosen;
      for (const VoPoint& p : vo.points) {
        if (p.observations < 3) continue;
        double range = INFINITY;
        for (const Frame& f : frames)
          range = std::min(range, (p.point_in_world - f.vo.translation).norm());
        const double sigma =
            range * s_true.scale / fx / std::sin(std::max(p.parallax_deg, 0.1) * M_PI / 180);
        if (sigma <= max_sigma) chosen.push_back(p.point_in_world);
      }
      std::printf("perfect map, sigma<=%g, %zu points: shift: within 0.1 / 0.2 m of a surface:",
                  max_sigma, chosen.size());
      for (double a = -2.0; a <= 2.01; a += 0.2) {
        Similarity3 s = s_true;
        s.translation += a * along;
        int c1 = 0, c2 = 0;
        for (const Eigen::Vector3d& p : chosen) {
          int kind;
          const double d = surface_distance(s * p, &kind);
          c1 += d < 0.1;
          c2 += d < 0.2;
        }
        std::printf(" %+.1f:%d/%d", a, c1, c2);
      }
      std::printf("\n");
    }
    // A dense LiDAR map: scans every 2 m along the query's true path, all around, up to +15 deg.
    LidarOptions lo;
    lo.scan_spacing_m = 2.0;
    lo.azimuth_fov_deg = 360.0;
    lo.max_elevation_deg = 15.0;
    std::vector<Rigid3d> sensors;
    for (size_t i = 0; i < frames.size(); i += 1) {
      const Eigen::Matrix3d r = frames[i].truth.rotation.toRotationMatrix();
      Eigen::Vector3d fwd = r.col(2);
      fwd.z() = 0;
      fwd.normalize();
      Eigen::Matrix3d m;
      m.col(0) = fwd;
      m.col(2) = Eigen::Vector3d::UnitZ();
      m.col(1) = m.col(2).cross(m.col(0));
      sensors.push_back(
          Rigid3d::FromMatrix(m, frames[i].truth.translation + Eigen::Vector3d(0, 0, 0.2)));
    }
    const std::vector<LidarPoint> scans = SimulateScans(world, sensors, lo, 7);
    PointCloud dense;
    for (const LidarPoint& lp : scans) dense.positions.push_back(lp.position);
    dense = VoxelFilter(dense, 0.2);
    StructureMap dmap(dense, ro);
    std::printf("dense map %zu points\n", dense.size());
    auto f = RegisterStructure(points, dmap, s_true, along, fine);
    std::printf("dense map: fine ICP from truth share %.2f rms %.3f\n", f.inlier_share, f.rms_m);
    Report("  result", f.map_from_world, frames);
    f = RegisterStructure(points, dmap, s_true, along, nos);
    Report("  full ICP from truth", f.map_from_world, frames);
    std::printf("dense map shift: count(plane<0.1 & point<0.4) / (plane<0.2):");
    PrintShiftProfile(points, dmap, s_true, along);
    for (double a : {-1.0, 0.0, 1.0}) {
      Similarity3 s = s_true;
      s.translation += a * along;
      auto g = RegisterStructure(points, dmap, s, along, fine);
      std::printf("dense map, fine ICP from truth %+.1f m along: share %.3f rms %.4f\n", a,
                  g.inlier_share, g.rms_m);
      Report("  result", g.map_from_world, frames);
    }
  }
  // Landscape along the road.
  std::printf("shift along  | fine ICP: share rms  final-horiz | occupied share\n");
  for (double a = -3.0; a <= 3.01; a += 0.25) {
    Similarity3 s = s_true;
    s.translation += a * along;
    const auto f = RegisterStructure(points, smap, s, along, fine);
    std::vector<double> h;
    for (const Frame& fr : frames)
      h.push_back((f.map_from_world * fr.vo.translation - fr.truth.translation).head<2>().norm());
    int occ = 0;
    for (const Eigen::Vector3d& p : points) occ += smap.Occupied(s * p) ? 1 : 0;
    std::printf("  %+5.2f  %.3f %.4f %.3f | %.3f\n", a, f.inlier_share, f.rms_m, Pct(h, 0.5),
                double(occ) / points.size());
  }
}

}  // namespace
}  // namespace epiloc

int main() {
  epiloc::Run();
  return 0;
}
