#include "epiloc/io/position_readers.h"

#include <cmath>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "epiloc/io/kitti.h"
#include "io_test_util.h"

namespace epiloc {
namespace {

// "$<body>*<checksum>".
std::string Nmea(const std::string& body) {
  unsigned checksum = 0;
  for (const char c : body) checksum ^= static_cast<unsigned char>(c);
  return fmt::format("${}*{:02X}\n", body, checksum);
}

constexpr double kDay19940323 = 8847.0 * 86400.0;  // 1994-03-23 00:00 UTC in UNIX seconds

TEST(Timestamps, ParsesKittiFormatWithFullPrecision) {
  const double t = ParseTimestamp("2011-09-26 13:04:32.351950336", "x");
  EXPECT_NEAR(t, 1317042272.351950336, 1e-6);
  EXPECT_NEAR(ParseTimestamp("1970-01-01 00:00:01", "x"), 1.0, 0.0);
  EXPECT_NEAR(ParseTimestamp("  12.25 ", "x"), 12.25, 0.0);
  ExpectError([] { ParseTimestamp("2011-13-26 13:04:32", "f.txt:3"); }, {"f.txt:3"});
  ExpectError([] { ParseTimestamp("2011-09-26 13:04:32.5x", "f.txt:4"); }, {"f.txt:4"});
  ExpectError([] { ParseTimestamp("abc", "f.txt:5"); }, {"f.txt:5"});
  // Issue 18 item 12: days beyond the month's end were accepted (2023-02-30 = March 2nd).
  ExpectError([] { ParseTimestamp("2023-02-30 00:00:00", "f.txt:6"); }, {"f.txt:6", "2023-02-30"});
  ExpectError([] { ParseTimestamp("2023-02-29 00:00:00", "f.txt:7"); }, {"f.txt:7"});
  ExpectError([] { ParseTimestamp("2023-04-31 00:00:00", "f.txt:8"); }, {"f.txt:8"});
  EXPECT_NEAR(ParseTimestamp("2024-02-29 00:00:00", "x") - ParseTimestamp("2024-02-28 00:00:00", "x"),
              86400.0, 0.0);
  EXPECT_NEAR(ParseTimestamp("2000-02-29 00:00:00", "x"), 951782400.0, 0.0);
  ExpectError([] { ParseTimestamp("1900-02-29 00:00:00", "f.txt:9"); }, {"f.txt:9"});
}

TEST(Timestamps, ReadsFileAndRejectsBackwards) {
  TempDir dir;
  WriteText(dir / "t.txt", "2011-09-26 13:04:32.1\n2011-09-26 13:04:32.2\n\n");
  const auto times = ReadTimestamps(dir / "t.txt");
  ASSERT_EQ(times.size(), 2u);
  EXPECT_NEAR(times[1] - times[0], 0.1, 1e-6);
  WriteText(dir / "back.txt", "1.0\n2.0\n1.5\n");
  ExpectError([&] { ReadTimestamps(dir / "back.txt"); }, {dir / "back.txt:3", "backwards"});
  WriteText(dir / "blank.txt", "1.0\n\n2.0\n");
  ExpectError([&] { ReadTimestamps(dir / "blank.txt"); }, {dir / "blank.txt:2"});
  ExpectError([&] { ReadTimestamps(dir / "absent.txt"); }, {dir / "absent.txt"});
}

TEST(PositionCsv, ReadsLatLonWithOrientationAndFrame) {
  TempDir dir;
  WriteText(dir / "p.csv",
            "timestamp_s,lat_deg,lon_deg,alt_m,qw,qx,qy,qz,frame\n"
            "# a comment\n"
            "10.0,49.0,8.4,110.5,1,0,0,0,7\n"
            "10.1,49.00001,8.40001,110.6,,,,,\n");
  const PositionTrack track = ReadPositionCsv(dir / "p.csv", std::nullopt);
  EXPECT_EQ(track.source, dir / "p.csv");
  ASSERT_EQ(track.samples.size(), 2u);
  EXPECT_EQ(track.samples[0].timestamp_s, 10.0);
  EXPECT_EQ(track.samples[0].position.lat_deg, 49.0);
  EXPECT_EQ(track.samples[0].position.lon_deg, 8.4);
  EXPECT_EQ(track.samples[0].position.alt_m, 110.5);
  ASSERT_TRUE(track.samples[0].enu_from_cam.has_value());
  EXPECT_EQ(track.samples[0].enu_from_cam->w(), 1.0);
  EXPECT_EQ(track.samples[0].frame, 7);
  EXPECT_FALSE(track.samples[1].enu_from_cam.has_value());
  EXPECT_EQ(track.samples[1].frame, kInvalidFrame);
}

TEST(PositionCsv, ReadsLocalXyzAboutOrigin) {
  TempDir dir;
  WriteText(dir / "p.csv", "timestamp_s,x_m,y_m,z_m\n0,0,0,0\n1,10,-5,2\n");
  const Geodetic origin{49.0, 8.4, 100.0};
  const PositionTrack track = ReadPositionCsv(dir / "p.csv", origin);
  ASSERT_EQ(track.samples.size(), 2u);
  const EnuFrame enu(origin);
  EXPECT_LT((enu.ToEnu(track.samples[0].position)).norm(), 1e-6);
  EXPECT_LT((enu.ToEnu(track.samples[1].position) - Eigen::Vector3d(10, -5, 2)).norm(), 1e-6);
  ExpectError([&] { ReadPositionCsv(dir / "p.csv", std::nullopt); }, {dir / "p.csv", "origin"});
}

TEST(PositionCsv, ResultCsvGivesOnlyOkRows) {
  // build-db --positions RESULT.csv: a lost row (its coordinates a stale guess or empty) must not
  // become a survey position.
  TempDir dir;
  WriteText(dir / "r.csv",
            "frame,timestamp_s,lat_deg,lon_deg,alt_m,s_m,db_frame,method,status\n"
            "0,0.0,49.0,8.0,100,0,0,online,ok\n"
            "1,0.1,10.0,10.0,100,,,online,lost\n"
            "2,0.2,,,,,,online,rejected\n"
            "3,0.3,49.0001,8.0,100,11,3,online,ok\n");
  const PositionTrack track = ReadPositionCsv(dir / "r.csv", std::nullopt);
  ASSERT_EQ(track.samples.size(), 2u);
  EXPECT_EQ(track.samples[0].frame, 0);
  EXPECT_EQ(track.samples[1].frame, 3);
  EXPECT_NEAR(track.samples[1].position.lat_deg, 49.0001, 1e-12);
}

TEST(PositionCsv, RejectsBadLines) {
  TempDir dir;
  const std::string header = "timestamp_s,lat_deg,lon_deg,alt_m\n";
  WriteText(dir / "lat.csv", header + "1,49,8,0\n2,95,8,0\n");
  ExpectError([&] { ReadPositionCsv(dir / "lat.csv", std::nullopt); },
              {dir / "lat.csv:3", "latitude"});
  WriteText(dir / "lon.csv", header + "1,49,-181,0\n");
  ExpectError([&] { ReadPositionCsv(dir / "lon.csv", std::nullopt); },
              {dir / "lon.csv:2", "longitude"});
  WriteText(dir / "equal.csv", header + "1,49,8,0\n1,49,8,0\n");
  ExpectError([&] { ReadPositionCsv(dir / "equal.csv", std::nullopt); }, {dir / "equal.csv:3"});
  WriteText(dir / "back.csv", header + "2,49,8,0\n1,49,8,0\n");
  ExpectError([&] { ReadPositionCsv(dir / "back.csv", std::nullopt); }, {dir / "back.csv:3"});
  WriteText(dir / "text.csv", header + "1,49,eight,0\n");
  ExpectError([&] { ReadPositionCsv(dir / "text.csv", std::nullopt); }, {dir / "text.csv:2"});
  WriteText(dir / "fields.csv", header + "1,49,8\n");
  ExpectError([&] { ReadPositionCsv(dir / "fields.csv", std::nullopt); }, {dir / "fields.csv:2"});
  WriteText(dir / "q.csv", "timestamp_s,lat_deg,lon_deg,alt_m,qw,qx,qy,qz\n1,49,8,0,2,0,0,0\n");
  ExpectError([&] { ReadPositionCsv(dir / "q.csv", std::nullopt); }, {dir / "q.csv:2", "unit"});
  WriteText(dir / "cols.csv", "timestamp_s,lat_deg,lon_deg\n1,49,8\n");
  ExpectError([&] { ReadPositionCsv(dir / "cols.csv", std::nullopt); },
              {dir / "cols.csv", "alt_m"});
}

TEST(Nmea, CombinesGgaAndRmcWithChecksums) {
  TempDir dir;
  // The first two lines are the classic NMEA examples with their published checksums.
  WriteText(dir / "log.nmea",
            "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\n"
            "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\n" +
                Nmea("GPGSV,2,1,08,01,40,083,46,02,17,308,41,12,07,344,39,14,22,228,45") +
                Nmea("GNGGA,123520.5,4807.100,N,01131.100,E,2,08,0.9,546.0,M,46.9,M,,") +
                Nmea("GPGGA,123521,,,,,0,00,,,M,,M,,") +
                Nmea("GPRMC,123522,V,4807.200,N,01131.200,E,0,0,230394,,") +
                Nmea("GNRMC,123523,A,4807.300,S,01131.300,W,0,0,230394,,") + "\n");
  NmeaStats stats;
  const PositionTrack track = ReadNmea(dir / "log.nmea", "", &stats);
  ASSERT_EQ(track.samples.size(), 3u);
  EXPECT_EQ(stats.positions, 3);
  EXPECT_EQ(stats.skipped_no_fix, 2);
  EXPECT_EQ(stats.ignored, 1);
  const auto& s0 = track.samples[0];
  EXPECT_DOUBLE_EQ(s0.timestamp_s, kDay19940323 + 12 * 3600 + 35 * 60 + 19);
  EXPECT_NEAR(s0.position.lat_deg, 48 + 7.038 / 60, 1e-12);
  EXPECT_NEAR(s0.position.lon_deg, 11 + 31.0 / 60, 1e-12);
  EXPECT_EQ(s0.position.alt_m, 545.4);
  EXPECT_DOUBLE_EQ(track.samples[1].timestamp_s, kDay19940323 + 12 * 3600 + 35 * 60 + 20.5);
  EXPECT_EQ(track.samples[1].position.alt_m, 546.0);
  // RMC only: southern / western hemisphere, altitude of the last GGA.
  EXPECT_NEAR(track.samples[2].position.lat_deg, -(48 + 7.3 / 60), 1e-12);
  EXPECT_NEAR(track.samples[2].position.lon_deg, -(11 + 31.3 / 60), 1e-12);
  EXPECT_EQ(track.samples[2].position.alt_m, 546.0);
}

TEST(Nmea, BadChecksumNamesTheLine) {
  TempDir dir;
  WriteText(dir / "bad.nmea",
            "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\n"
            "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*48\n");
  ExpectError([&] { ReadNmea(dir / "bad.nmea"); }, {dir / "bad.nmea:2", "checksum"});
}

TEST(Nmea, GgaBeforeRmcNeedsADate) {
  TempDir dir;
  WriteText(dir / "gga.nmea",
            Nmea("GPGGA,235959,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,") +
                Nmea("GPGGA,000000.5,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,"));
  ExpectError([&] { ReadNmea(dir / "gga.nmea"); }, {dir / "gga.nmea:1", "date"});
  const PositionTrack track = ReadNmea(dir / "gga.nmea", "1994-03-23");
  ASSERT_EQ(track.samples.size(), 2u);
  EXPECT_DOUBLE_EQ(track.samples[0].timestamp_s, kDay19940323 + 86399);
  EXPECT_DOUBLE_EQ(track.samples[1].timestamp_s,
                   kDay19940323 + 86400.5);  // crossed midnight
}

TEST(Nmea, DatesFromRmcAcrossMidnightAndLongGaps) {
  TempDir dir;
  WriteText(dir / "days.nmea",
            Nmea("GPRMC,235959.5,A,4807.038,N,01131.000,E,0,0,230394,,") +
                Nmea("GPGGA,000000,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,") +
                Nmea("GPRMC,000000,A,4807.038,N,01131.000,E,0,0,240394,,") +
                Nmea("GPRMC,100000,A,4807.038,N,01131.000,E,0,0,260394,,"));
  const PositionTrack track = ReadNmea(dir / "days.nmea");
  ASSERT_EQ(track.samples.size(), 3u);  // GGA and RMC at midnight are one epoch
  EXPECT_DOUBLE_EQ(track.samples[0].timestamp_s, kDay19940323 + 86399.5);
  EXPECT_DOUBLE_EQ(track.samples[1].timestamp_s, kDay19940323 + 86400);
  EXPECT_EQ(track.samples[1].position.alt_m, 545.4);
  EXPECT_DOUBLE_EQ(track.samples[2].timestamp_s, kDay19940323 + 3 * 86400 + 36000);
}

TEST(Nmea, RejectsMalformedSentences) {
  TempDir dir;
  WriteText(dir / "short.nmea", Nmea("GPRMC,123519,A,4807.038,N"));
  ExpectError([&] { ReadNmea(dir / "short.nmea"); }, {dir / "short.nmea:1"});
  WriteText(dir / "junk.nmea", "hello\n");
  ExpectError([&] { ReadNmea(dir / "junk.nmea"); }, {dir / "junk.nmea:1"});
  WriteText(dir / "hemi.nmea", Nmea("GPRMC,123519,A,4807.038,X,01131.000,E,0,0,230394,,"));
  ExpectError([&] { ReadNmea(dir / "hemi.nmea"); }, {dir / "hemi.nmea:1", "hemisphere"});
  WriteText(dir / "back.nmea", Nmea("GPRMC,123519,A,4807.038,N,01131.000,E,0,0,230394,,") +
                                   Nmea("GPRMC,123518,A,4807.038,N,01131.000,E,0,0,230394,,"));
  ExpectError([&] { ReadNmea(dir / "back.nmea"); }, {dir / "back.nmea:2", "backwards"});
  WriteText(dir / "feb30.nmea", Nmea("GPRMC,123519,A,4807.038,N,01131.000,E,0,0,300223,,"));
  ExpectError([&] { ReadNmea(dir / "feb30.nmea"); }, {dir / "feb30.nmea:1", "300223"});
}

// Writes a KITTI-style OXTS folder with `n` records 0.1 s apart, moving north-east.
void WriteOxts(const std::string& oxts_dir, int n) {
  std::string times;
  for (int i = 0; i < n; ++i) {
    std::string values =
        fmt::format("{} {} 100.5 0.01 -0.02 {}", 49.0 + i * 1e-5, 8.4 + i * 1e-5, 0.5 + i * 0.01);
    for (int k = 6; k < 30; ++k) values += " 0";
    WriteText(fmt::format("{}/data/{:010d}.txt", oxts_dir, i), values + "\n");
    times += fmt::format("2011-09-26 13:04:32.{:09d}\n", 100000000 * i + 123);
  }
  WriteText(oxts_dir + "/timestamps.txt", times);
}

TEST(KittiOxts, ReadsFolder) {
  TempDir dir;
  WriteOxts(dir / "oxts", 4);
  const PositionTrack track = ReadPositions(dir / "oxts", ParsePositionFormat("kitti_oxts", "x"));
  ASSERT_EQ(track.samples.size(), 4u);
  EXPECT_EQ(track.samples[2].frame, 2);
  EXPECT_NEAR(track.samples[2].timestamp_s, 1317042272.2000001, 1e-6);
  EXPECT_DOUBLE_EQ(track.samples[3].position.lat_deg, 49.00003);
  EXPECT_EQ(track.samples[3].position.alt_m, 100.5);
  EXPECT_FALSE(track.samples[0].enu_from_cam.has_value());
  const auto records = ReadKittiOxts(dir / "oxts");
  EXPECT_DOUBLE_EQ(records[1].yaw_rad, 0.51);
  EXPECT_DOUBLE_EQ(records[1].roll_rad, 0.01);
  EXPECT_DOUBLE_EQ(records[1].pitch_rad, -0.02);
  EXPECT_EQ(records[1].values.size(), 30u);
}

TEST(KittiOxts, RejectsBadFiles) {
  TempDir dir;
  WriteOxts(dir / "oxts", 3);
  WriteText(dir / "oxts/data/0000000001.txt", "49 8 100\n");
  ExpectError([&] { ReadKittiOxtsTrack(dir / "oxts"); },
              {dir / "oxts/data/0000000001.txt:1", "30"});
  WriteOxts(dir / "oxts2", 3);
  std::string zeros;
  for (int k = 0; k < 30; ++k) zeros += "0 ";
  WriteText(dir / "oxts2/data/0000000003.txt", zeros);
  ExpectError([&] { ReadKittiOxtsTrack(dir / "oxts2"); },
              {dir / "oxts2/timestamps.txt", "frame 3"});
  WriteOxts(dir / "oxts3", 3);
  WriteText(dir / "oxts3/timestamps.txt", "1.0\n2.0\n2.0\n");
  ExpectError([&] { ReadKittiOxtsTrack(dir / "oxts3"); }, {dir / "oxts3/timestamps.txt:3"});
}

TEST(PositionFormat, UnknownNameIsAnError) {
  EXPECT_EQ(ParsePositionFormat("nmea", "x"), PositionFormat::kNmea);
  EXPECT_EQ(PositionFormatName(PositionFormat::kKittiOxts), "kitti_oxts");
  ExpectError([] { ParsePositionFormat("gpx", "drive.json: gnss"); }, {"drive.json", "gpx"});
}

TEST(PositionCsv, WriteReadRoundTripIsExact) {
  TempDir dir;
  PositionTrack track;
  PositionSample a;
  a.timestamp_s = 1317042272.351950336;
  a.position = {49.011212804408, 8.4228850417969, 112.83492279053};
  a.enu_from_cam =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  a.frame = 4;
  PositionSample b = a;
  b.timestamp_s += 0.1;
  b.enu_from_cam.reset();
  b.frame = kInvalidFrame;
  track.samples = {a, b};
  WritePositionCsv(track, dir / "p.csv");
  const PositionTrack read = ReadPositionCsv(dir / "p.csv", std::nullopt);
  ASSERT_EQ(read.samples.size(), 2u);
  EXPECT_TRUE(read.samples[0] == a);
  EXPECT_TRUE(read.samples[1] == b);
}

}  // namespace
}  // namespace epiloc
