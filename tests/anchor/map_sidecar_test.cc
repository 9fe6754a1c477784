#include "epiloc/anchor/map_sidecar.h"

#include <gtest/gtest.h>

#include "epiloc/db/database.h"
#include "test_util.h"

namespace epiloc {
namespace {

MapSidecar TestSidecar() {
  MapSidecar s;
  s.enu_origin = {49.011202647638739, 8.4228859137485853, 113.55769249049808};
  s.origin_source = "first ground-truth position of drive kitti";
  s.source_drive = "kitti";
  s.source_dir = "/data/kitti";
  s.voxel_m = 0.05;
  s.num_points = 1234567;
  s.num_scans = 31;
  s.attributes = {"intensity", "rgb"};
  s.colour_mode = "closest";
  s.colour_frames = 154;
  s.coloured_points = 1000000;
  s.bounds.Extend(Eigen::Vector3f(-11.5f, -94.25f, -2.5f));
  s.bounds.Extend(Eigen::Vector3f(64.5f, -2.75f, 3.5f));
  s.created_by = "epiloc 0.1.0";
  return s;
}

TEST(MapSidecar, RoundTripsEveryField) {
  TempDir dir;
  const std::string path = dir / "map.ply.json";
  const MapSidecar s = TestSidecar();
  WriteMapSidecar(s, path);
  const MapSidecar r = ReadMapSidecar(path);
  EXPECT_EQ(r.enu_origin.lat_deg, s.enu_origin.lat_deg);  // exact: doubles round-trip
  EXPECT_EQ(r.enu_origin.lon_deg, s.enu_origin.lon_deg);
  EXPECT_EQ(r.enu_origin.alt_m, s.enu_origin.alt_m);
  EXPECT_EQ(r.origin_source, s.origin_source);
  EXPECT_EQ(r.source_drive, s.source_drive);
  EXPECT_EQ(r.source_dir, s.source_dir);
  EXPECT_EQ(r.voxel_m, s.voxel_m);
  EXPECT_EQ(r.num_points, s.num_points);
  EXPECT_EQ(r.num_scans, s.num_scans);
  EXPECT_EQ(r.attributes, s.attributes);
  EXPECT_EQ(r.colour_mode, s.colour_mode);
  EXPECT_EQ(r.colour_frames, s.colour_frames);
  EXPECT_EQ(r.coloured_points, s.coloured_points);
  EXPECT_EQ(r.bounds.min, s.bounds.min);
  EXPECT_EQ(r.bounds.max, s.bounds.max);
  EXPECT_EQ(r.created_by, s.created_by);
  EXPECT_EQ(SidecarPath(dir / "map.ply"), path);
  EXPECT_EQ(SidecarPath(dir / "tiles/"), dir / "tiles.json");
  ASSERT_TRUE(FindMapSidecar(dir / "map.ply").has_value());
  EXPECT_FALSE(FindMapSidecar(dir / "other.ply").has_value());
}

TEST(MapSidecar, RejectsMalformedSidecarsNamingTheFile) {
  TempDir dir;
  const std::string path = dir / "bad.json";
  WriteText(path, "{\"format\": \"epiloc-map\", \"version\": 1, \"enu_origin\": "
                  "{\"lat_deg\": 49, \"lon_deg\": 8, \"alt_m\": 1}, \"colur\": {}}");
  ExpectError([&] { ReadMapSidecar(path); }, {path, "unknown key 'colur'"});
  WriteText(path, "{\"format\": \"epiloc-map\", \"version\": 1, \"enu_origin\": "
                  "{\"lat_deg\": 95, \"lon_deg\": 8, \"alt_m\": 1}}");
  ExpectError([&] { ReadMapSidecar(path); }, {path, "latitude 95"});
  WriteText(path, "{\"format\": \"epiloc-map\", \"version\": 2}");
  ExpectError([&] { ReadMapSidecar(path); }, {path, "version 2 not supported"});
  WriteText(path, "{\"format\": \"something\"}");
  ExpectError([&] { ReadMapSidecar(path); }, {path, "not an epiloc map sidecar"});
  WriteText(path, "ply\nformat ascii 1.0\n");
  ExpectError([&] { ReadMapSidecar(path); }, {path, "not a JSON map sidecar"});
  WriteText(path, "{\"format\": \"epiloc-map\", \"version\": 1}");
  ExpectError([&] { ReadMapSidecar(path); }, {path, "missing key 'enu_origin'"});
}

TEST(MapSidecar, ParsesGeodeticOptions) {
  const Geodetic g = ParseGeodetic("49.5, 8.25,110", "--cloud-origin");
  EXPECT_EQ(g.lat_deg, 49.5);
  EXPECT_EQ(g.lon_deg, 8.25);
  EXPECT_EQ(g.alt_m, 110.0);
  ExpectError([] { ParseGeodetic("49,8", "--cloud-origin"); }, {"--cloud-origin '49,8'"});
  ExpectError([] { ParseGeodetic("49,8,x", "--cloud-origin"); }, {"LAT,LON,ALT"});
  ExpectError([] { ParseGeodetic("49,190,0", "--origin"); }, {"--origin", "longitude 190"});
}

TEST(MapSidecar, ResolvesTheOriginByPrecedence) {
  TempDir dir;
  const std::string cloud = dir / "map.ply";
  WriteText(cloud, "");
  MapOriginInputs inputs{cloud, std::nullopt, ""};
  ExpectError([&] { ResolveMapOrigin(inputs); },
              {cloud, "no sidecar", "--cloud-origin LAT,LON,ALT or --db"});

  // A database's origin.
  const std::string db_path = dir / "route.sqlite";
  {
    Database db(db_path);
    db.SetEnuOrigin({49.1, 8.5, 120.0});
  }
  inputs.db_path = db_path;
  MapOrigin origin = ResolveMapOrigin(inputs);
  EXPECT_EQ(origin.enu_origin.lat_deg, 49.1);
  EXPECT_EQ(origin.source, "database " + db_path);

  // A sidecar beats the database; an explicit origin beats both.
  MapSidecar s = TestSidecar();
  WriteMapSidecar(s, SidecarPath(cloud));
  origin = ResolveMapOrigin(inputs);
  EXPECT_EQ(origin.enu_origin.lat_deg, s.enu_origin.lat_deg);
  ASSERT_TRUE(origin.sidecar.has_value());
  inputs.explicit_origin = Geodetic{48.0, 9.0, 10.0};
  origin = ResolveMapOrigin(inputs);
  EXPECT_EQ(origin.enu_origin.lat_deg, 48.0);
  EXPECT_EQ(origin.source, "--cloud-origin");

  Database(dir / "empty.sqlite");
  inputs = {cloud + ".none", std::nullopt, dir / "empty.sqlite"};
  ExpectError([&] { ResolveMapOrigin(inputs); }, {"empty.sqlite", "no ENU origin"});
}

}  // namespace
}  // namespace epiloc
