#include "epiloc/eval/export.h"

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "epiloc/eval/truth.h"
#include "eval_test_util.h"

namespace epiloc {
namespace {

using V = Eigen::Vector3d;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// A curved track of `method` in UNIX time, plus a lost row and a second method.
ResultTable Track() {
  ResultTable table;
  table.path = "track.csv";
  table.extra_columns = {"quality"};
  for (int i = 0; i < 6; ++i) {
    ResultRow row =
        OkRow("pnp", i, 1317042272.35 + 0.1 * i, V(3.0 * i, 0.2 * i * i, 0.1 * i + 1.0 / 3.0));
    row.extra = {std::to_string(i)};
    table.rows.push_back(row);
  }
  ResultRow lost = StatusRow("pnp", 6, 1317042273.0, ResultStatus::kLost);
  lost.extra = {""};
  table.rows.push_back(lost);
  ResultRow gps = OkRow("gps", 0, 12.5, V(1, 1, 0));
  gps.extra = {""};
  table.rows.push_back(gps);
  return table;
}

double EnuDistance(const Geodetic& a, const Geodetic& b) { return EnuFrame(a).ToEnu(b).norm(); }

TEST(Export, TumRoundTripGivesTheSamePositions) {
  TempDir dir;
  const ResultTable table = Track();
  ExportOptions options;
  options.format = TrajectoryFormat::kTum;
  options.method = "pnp";
  options.origin = Geodetic{49.0001, 8.4001, 90.0};
  const ExportSummary summary = ExportTrajectory(table, options, dir / "t.tum");
  EXPECT_EQ(summary.rows, 6);  // the lost row is not exported
  TruthOptions read;
  read.origin = options.origin;
  const PositionTrack back = ReadTruth(dir / "t.tum", read);
  ASSERT_EQ(back.samples.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_LT(EnuDistance(back.samples[i].position, table.rows[i].position), 1e-6) << i;
    EXPECT_NEAR(back.samples[i].timestamp_s, table.rows[i].timestamp_s, 1e-6);
  }
}

TEST(Export, TumOrientationFollowsTheTrackOrTheQuaternion) {
  TempDir dir;
  ResultTable table;
  table.path = "north.csv";
  for (int i = 0; i < 3; ++i) table.rows.push_back(OkRow("vo", i, i, V(0, 2.0 * i, 0)));
  table.rows[2].enu_from_cam = Eigen::Quaterniond(0.5, 0.5, 0.5, 0.5);
  ExportOptions options;
  options.format = TrajectoryFormat::kTum;
  options.origin = TestOrigin();
  ExportTrajectory(table, options, dir / "n.tum");
  std::istringstream in(ReadAll(dir / "n.tum"));
  std::string line;
  std::getline(in, line);  // comment
  double t, x, y, z, qx, qy, qz, qw;
  in >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
  const Eigen::Quaterniond q(qw, qx, qy, qz);
  // Heading north: the camera's z (forward) points north, x (right) east, y (down) down.
  EXPECT_LT((q * V(0, 0, 1) - V(0, 1, 0)).norm(), 1e-9);
  EXPECT_LT((q * V(1, 0, 0) - V(1, 0, 0)).norm(), 1e-9);
  EXPECT_LT((q * V(0, 1, 0) - V(0, 0, -1)).norm(), 1e-9);
  std::getline(in, line);
  std::getline(in, line);
  std::getline(in, line);
  std::istringstream third(line);
  third >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
  EXPECT_NEAR(t, 2.0, 0.0);
  EXPECT_NEAR(qw, 0.5, 1e-6);  // the row's own orientation (ENU axes differ by ~1e-7 rad at 4 m)
  EXPECT_NEAR(qx, 0.5, 1e-6);
}

TEST(Export, KittiRoundTripThroughTheKittiPosesReader) {
  TempDir dir;
  const ResultTable table = Track();
  ExportOptions options;
  options.format = TrajectoryFormat::kKitti;
  options.method = "pnp";
  const ExportSummary summary = ExportTrajectory(table, options, dir / "poses.txt");
  EXPECT_EQ(summary.times_path, dir / "poses_times.txt");
  // Default origin: the first exported row.
  EXPECT_EQ(summary.origin.lat_deg, table.rows[0].position.lat_deg);
  TruthOptions read;
  read.format = TruthFormat::kKittiPoses;
  read.origin = summary.origin;
  read.times_path = summary.times_path;
  const PositionTrack back = ReadTruth(dir / "poses.txt", read);
  ASSERT_EQ(back.samples.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_LT(EnuDistance(back.samples[i].position, table.rows[i].position), 1e-6) << i;
    EXPECT_NEAR(back.samples[i].timestamp_s, table.rows[i].timestamp_s, 1e-6);
  }
  // First pose: at the origin, rotation orthonormal.
  std::istringstream in(ReadAll(dir / "poses.txt"));
  Eigen::Matrix<double, 3, 4> p;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) in >> p(r, c);
  }
  EXPECT_LT(p.col(3).norm(), 1e-9);
  EXPECT_LT((p.leftCols<3>() * p.leftCols<3>().transpose() - Eigen::Matrix3d::Identity()).norm(),
            1e-9);
}

TEST(Export, GeoJsonHasALineStringPerMethodAndPoints) {
  TempDir dir;
  const ResultTable table = Track();
  ExportOptions options;
  options.format = TrajectoryFormat::kGeoJson;
  const ExportSummary summary = ExportTrajectory(table, options, dir / "t.geojson");
  EXPECT_EQ(summary.methods, (std::vector<std::string>{"gps", "pnp"}));
  const auto j = nlohmann::json::parse(ReadAll(dir / "t.geojson"));
  EXPECT_EQ(j["type"], "FeatureCollection");
  const nlohmann::json* line = nullptr;
  int points = 0;
  for (const auto& f : j["features"]) {
    if (f["geometry"]["type"] == "LineString") {
      EXPECT_EQ(f["properties"]["method"], "pnp");  // gps has one point only: no line
      line = &f;
    } else {
      ++points;
    }
  }
  EXPECT_EQ(points, 7);  // 6 pnp + 1 gps
  ASSERT_NE(line, nullptr);
  const auto& coords = (*line)["geometry"]["coordinates"];
  ASSERT_EQ(coords.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(coords[i][0].get<double>(), table.rows[i].position.lon_deg);
    EXPECT_EQ(coords[i][1].get<double>(), table.rows[i].position.lat_deg);
    EXPECT_EQ(coords[i][2].get<double>(), table.rows[i].position.alt_m);
  }
  const auto& point = j["features"][2];  // gps point, pnp line, pnp frame 0
  EXPECT_EQ(point["geometry"]["type"], "Point");
  EXPECT_EQ(point["properties"]["frame"], 0);
  EXPECT_EQ(point["properties"]["status"], "ok");
  EXPECT_EQ(point["properties"]["quality"], "0");
}

TEST(Export, GpxAndKml) {
  TempDir dir;
  const ResultTable table = Track();
  ExportOptions options;
  options.format = TrajectoryFormat::kGpx;
  ExportTrajectory(table, options, dir / "t.gpx");
  const std::string gpx = ReadAll(dir / "t.gpx");
  EXPECT_NE(gpx.find("<time>2011-09-26T13:04:32.350Z</time>"), std::string::npos) << gpx;
  EXPECT_NE(gpx.find("<trk><name>gps</name>"), std::string::npos);
  EXPECT_EQ(gpx.find("1970-"), std::string::npos);  // gps at t = 12.5 s gets no time
  EXPECT_NE(gpx.find(fmt::format("lat=\"{:.9f}\"", table.rows[3].position.lat_deg)),
            std::string::npos);
  options.format = TrajectoryFormat::kKml;
  ExportTrajectory(table, options, dir / "t.kml");
  const std::string kml = ReadAll(dir / "t.kml");
  EXPECT_NE(kml.find("<kml xmlns=\"http://www.opengis.net/kml/2.2\">"), std::string::npos);
  EXPECT_NE(kml.find(fmt::format("{:.9f},{:.9f}", table.rows[5].position.lon_deg,
                                 table.rows[5].position.lat_deg)),
            std::string::npos);
  EXPECT_EQ(IsoTimeOfUnixSeconds(0.0), std::nullopt);
  EXPECT_EQ(*IsoTimeOfUnixSeconds(1e9), "2001-09-09T01:46:40.000Z");
}

TEST(Export, RejectsBadRequests) {
  TempDir dir;
  const ResultTable table = Track();
  ExportOptions options;
  options.format = TrajectoryFormat::kTum;
  ExpectError([&] { ExportTrajectory(table, options, dir / "x.tum"); },
              {"track.csv", "gps, pnp", "--method"});
  options.method = "vo";
  ExpectError([&] { ExportTrajectory(table, options, dir / "x.tum"); },
              {"track.csv", "no rows of method 'vo'"});
  ResultTable lost;
  lost.path = "lost.csv";
  lost.rows.push_back(StatusRow("vo", 1, 1.0, ResultStatus::kLost));
  ExpectError([&] { ExportTrajectory(lost, options, dir / "x.tum"); },
              {"lost.csv", "no rows with status ok"});
  ExpectError([] { ParseTrajectoryFormat("shp"); }, {"unknown export format 'shp'", "geojson"});
  options.method = "pnp";
  WriteText(dir / "file.txt", "a file, not a folder\n");
  ExpectError([&] { ExportTrajectory(table, options, dir / "file.txt/x.tum"); },
              {"file.txt/x.tum", "cannot open"});
  ExportTrajectory(table, options, dir / "new/folder/x.tum");  // folders are created
}

}  // namespace
}  // namespace epiloc
