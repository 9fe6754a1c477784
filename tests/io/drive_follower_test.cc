// Following a drive that is still being written, and the NMEA output of a localizer.
#include "epiloc/io/drive_follower.h"

#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "epiloc/io/nmea_writer.h"
#include "epiloc/io/position_readers.h"
#include "io_test_util.h"

namespace epiloc {
namespace {

using Json = nlohmann::json;

// A drive.json with frames from frames.csv and GNSS from `gnss_file` in `format`.
void WriteManifest(const TempDir& dir, const std::string& gnss_file, const std::string& format) {
  const Json manifest = {
      {"epiloc_drive", 1},
      {"name", "growing"},
      {"camera",
       {{"width", 32}, {"height", 24}, {"fx", 30.0}, {"fy", 30.0}, {"cx", 15.5}, {"cy", 11.5}}},
      {"frames", {{"csv", "frames.csv"}}},
      {"gnss", {{"file", gnss_file}, {"format", format}}},
      {"max_gap_s", 1.5},
      {"time_offset_s", 0.25}};
  WriteText(dir / "drive.json", manifest.dump(2));
}

void Append(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::app);
  out << text;
}

TEST(DriveFollower, ReadsRowsAsTheyAreAppendedCompleteLinesOnly) {
  TempDir dir;
  WriteManifest(dir, "gnss.csv", "csv");
  for (int i = 0; i < 3; ++i) {
    WriteImage(dir / fmt::format("images/{}.png", i), Pattern(32, 24, CV_8UC1, i));
  }
  DriveFollower follower(dir.str());
  EXPECT_EQ(follower.manifest().camera.width, 32);
  EXPECT_TRUE(follower.has_gnss());
  // Nothing written yet: no frames, no GNSS.
  EXPECT_TRUE(follower.PollFrames().empty());
  EXPECT_FALSE(follower.GnssAt(10.0).has_value());

  WriteText(dir / "frames.csv", "frame,timestamp_s,image\n0,10.0,images/0.png\n1,10.1,ima");
  std::vector<FrameRecord> frames = follower.PollFrames();
  ASSERT_EQ(frames.size(), 1u);  // the second row is still being written
  EXPECT_EQ(frames[0].frame, 0);
  Append(dir / "frames.csv", "ges/1.png\n2,10.2,images/2.png\n");
  frames = follower.PollFrames();
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].frame, 1);
  EXPECT_EQ(frames[0].image, "images/1.png");
  EXPECT_DOUBLE_EQ(frames[1].timestamp_s, 10.2);
  EXPECT_TRUE(follower.PollFrames().empty());

  // GNSS in the file's clock; time_offset_s 0.25 maps it to the frames' clock.
  WriteText(dir / "gnss.csv",
            "timestamp_s,lat_deg,lon_deg,alt_m\n9.75,49.0,8.4,100\n10.75,49.0001,8.4,100\n");
  const std::optional<PositionSample> mid = follower.GnssAt(10.5);
  ASSERT_TRUE(mid.has_value());
  EXPECT_NEAR(mid->position.lat_deg, 49.00005, 1e-9);
  EXPECT_DOUBLE_EQ(mid->timestamp_s, 10.5);
  // Past the last sample: extrapolated within max_gap_s, none beyond.
  ASSERT_TRUE(follower.GnssAt(11.5).has_value());
  EXPECT_NEAR(follower.GnssAt(11.5)->position.lat_deg, 49.00015, 1e-9);
  EXPECT_FALSE(follower.GnssAt(13.0).has_value());
  Append(dir / "gnss.csv", "12.75,49.0003,8.4,100\n");
  ASSERT_TRUE(follower.GnssAt(13.0).has_value());
  EXPECT_NEAR(follower.GnssAt(13.0)->position.lat_deg, 49.0003, 1e-9);
}

TEST(DriveFollower, RejectsBadRowsAndUnfollowableDrives) {
  TempDir dir;
  WriteManifest(dir, "gnss.csv", "csv");
  WriteImage(dir / "images/0.png", Pattern(32, 24, CV_8UC1));
  DriveFollower follower(dir.str());
  WriteText(dir / "frames.csv",
            "frame,timestamp_s,image\n0,10.0,images/0.png\n0,10.1,images/0.png\n");
  ExpectError([&] { follower.PollFrames(); }, {"frames.csv:3", "frame 0 appears twice"});

  TempDir missing_image;
  WriteManifest(missing_image, "gnss.csv", "csv");
  DriveFollower follower2(missing_image.str());
  WriteText(missing_image / "frames.csv", "frame,timestamp_s,image\n0,10.0,images/9.png\n");
  ExpectError([&] { follower2.PollFrames(); }, {"frames.csv:2", "not found"});

  TempDir oxts;
  WriteManifest(oxts, "oxts", "kitti_oxts");
  ExpectError([&] { DriveFollower f(oxts.str()); },
              {"drive.json", "kitti_oxts", "cannot be followed"});
}

TEST(DriveFollower, FollowsAnNmeaLog) {
  TempDir dir;
  WriteManifest(dir, "gnss.nmea", "nmea");
  DriveFollower follower(dir.str());
  const double t0 = 1700000000.0;
  const Geodetic a{49.0, 8.4, 110.0}, b{49.0001, 8.4001, 111.0};
  {
    std::ofstream out(dir / "gnss.nmea");
    out << FormatRmc(t0, a, std::nullopt, std::nullopt) << "\r\n"
        << FormatGga(t0, a) << "\r\n"
        << FormatRmc(t0 + 1, b, std::nullopt, std::nullopt) << "\r\n"
        << FormatGga(t0 + 1, b);
  }
  // The last GGA has no line end yet: only the first epoch and the second's RMC are read.
  std::optional<PositionSample> fix = follower.GnssAt(t0 + 0.25);
  ASSERT_TRUE(fix.has_value());
  EXPECT_NEAR(fix->position.lat_deg, a.lat_deg, 1e-9);
  Append(dir / "gnss.nmea", "\r\n");
  fix = follower.GnssAt(t0 + 1.25);
  ASSERT_TRUE(fix.has_value());
  EXPECT_NEAR(fix->position.lat_deg, b.lat_deg, 1e-9);
  EXPECT_NEAR(fix->position.alt_m, b.alt_m, 1e-3);  // the GGA's altitude
}

TEST(NmeaWriter, ChecksumsAndFieldsOfTheSentences) {
  // The checksum of the textbook GGA example.
  EXPECT_EQ(NmeaChecksum("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), "47");
  const double t = 1317042272.46;  // 2011-09-26 13:04:32.46 UTC
  const Geodetic p{-33.8567844, -151.2152967, 42.125};
  const std::string gga = FormatGga(t, p);
  EXPECT_EQ(gga.substr(0, gga.find('*')),
            "$GPGGA,130432.46,3351.4070640,S,15112.9178020,W,6,00,,42.125,M,0.0,M,,");
  const std::string rmc = FormatRmc(t, p, 10.0, 84.4);
  EXPECT_EQ(rmc.substr(0, rmc.find('*')),
            "$GPRMC,130432.46,A,3351.4070640,S,15112.9178020,W,19.438,84.40,260911,,,E");
  EXPECT_EQ(rmc.substr(rmc.find('*') + 1), NmeaChecksum(rmc.substr(1, rmc.find('*') - 1)));
}

TEST(NmeaWriter, WrittenEpochsReadBackWithinAMillimetre) {
  TempDir dir;
  const EnuFrame enu(Geodetic{48.99, 8.39, 115.0});
  std::vector<Geodetic> written;
  {
    NmeaWriter writer(dir / "out.nmea");
    for (int i = 0; i < 20; ++i) {
      written.push_back(enu.ToGeodetic(Eigen::Vector3d(1.37 * i, -0.61 * i, 0.01 * i)));
      writer.Write(1700000000.0 + 0.1 * i, written.back());
    }
    writer.Close();
  }
  const PositionTrack track = ReadNmea(dir / "out.nmea");
  ASSERT_EQ(track.samples.size(), written.size());
  for (size_t i = 0; i < written.size(); ++i) {
    EXPECT_NEAR(track.samples[i].timestamp_s, 1700000000.0 + 0.1 * i, 1e-6);
    EXPECT_LT(EnuFrame(written[i]).ToEnu(track.samples[i].position).norm(), 1e-3) << i;
  }
  // Speed and course from consecutive epochs: 1.50 m per 0.1 s = 15.0 m/s = 29.16 knots, course
  // atan2(east 1.37, north -0.61) = 114.0 deg.
  std::ifstream in(dir / "out.nmea");
  std::string first, second, third;
  std::getline(in, first);
  std::getline(in, second);
  std::getline(in, third);
  EXPECT_NE(first.find("RMC,"), std::string::npos);
  EXPECT_NE(first.find(",E,,,"), std::string::npos) << "no speed or course at the first epoch";
  EXPECT_NE(third.find(",29.1"), std::string::npos) << third;
  EXPECT_NE(third.find(",114.0"), std::string::npos) << third;
}

}  // namespace
}  // namespace epiloc
