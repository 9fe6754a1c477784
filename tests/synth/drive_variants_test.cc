// Speed profiles and lines of the query variants (issue 14), on a bare world (a centreline, no
// surfaces: DrivePath needs nothing else).
#include <cmath>

#include <gtest/gtest.h>

#include "epiloc/core/error.h"
#include "epiloc/synth/drive_gen.h"

namespace epiloc {
namespace {

// A street without surfaces: straight 60 m from s = -30, a left arc of radius 40 m turning
// 80 deg, straight 50 m, a right arc of radius 30 m turning 60 deg, straight to s = 400.
World BareWorld() {
  World world;
  std::vector<CentrelinePiece> pieces;
  const auto add = [&](double length_m, double curvature_per_m) {
    CentrelinePiece p;
    p.s0_m = -30.0;
    if (!pieces.empty()) {
      const Centreline so_far(pieces);
      p.s0_m = so_far.end_s_m();
      p.start_in_world = so_far.PointAt(p.s0_m);
      p.start_yaw_rad = so_far.YawAt(p.s0_m);
    } else {
      p.start_in_world = Eigen::Vector2d(-30.0, 0.0);
    }
    p.length_m = length_m;
    p.curvature_per_m = curvature_per_m;
    pieces.push_back(p);
  };
  add(60, 0);
  add(40 * 80 * M_PI / 180, 1.0 / 40);
  add(50, 0);
  add(30 * 60 * M_PI / 180, -1.0 / 30);
  add(400, 0);
  world.centreline = Centreline(pieces);
  return world;
}

// A query drive with one constant speed, no stops, no wobble.
DriveOptions PlainQuery(double speed_mps, double rate_hz) {
  DriveOptions drive = DriveOptions::Query();
  drive.sections.clear();
  drive.stops.clear();
  drive.speed_mps = speed_mps;
  drive.frame_rate_hz = rate_hz;
  drive.wobble_yaw_deg = drive.wobble_pitch_deg = 0.0;
  drive.start_offset_m = 0.0;
  drive.end_offset_m = 0.0;
  drive.constant_acceleration = true;
  return drive;
}

std::vector<double> FrameS(const DrivePath& path) {
  std::vector<double> s;
  for (const double t : path.FrameTimes()) s.push_back(path.SAt(t));
  return s;
}

bool SamePose(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation.coeffs() == b.rotation.coeffs() && a.translation == b.translation;
}

TEST(DriveVariants, StopsGiveRepeatedFrames) {
  const World world = BareWorld();
  DriveOptions drive = DriveOptions::Query();  // wobble on
  drive.stops = {{0.0, 4.0, 25.0}};            // 4 s at 25 m from the start
  drive.still_when_stopped = true;
  const DrivePath path(world, drive, 100.0, 3);
  const std::vector<double> times = path.FrameTimes();
  int repeated = 0, longest = 0, run = 0;
  double stop_s = 0;
  for (size_t i = 1; i < times.size(); ++i) {
    if (SamePose(path.CamFromWorld(times[i]), path.CamFromWorld(times[i - 1]))) {
      ++repeated;
      longest = std::max(longest, ++run);
      stop_s = path.SAt(times[i]);
    } else {
      run = 0;
    }
  }
  std::printf("stop: %d repeated frames, longest run %d, at s = %.2f m\n", repeated, longest,
              stop_s);
  // 4 s at 15 Hz: 60 frames, 59 of them repeat their predecessor (one more may fall on a knot).
  EXPECT_GE(longest, 58);
  EXPECT_LE(repeated, 61);
  EXPECT_NEAR(stop_s, drive.start_offset_m + 25.0, 0.05);
  // Without a still stand the camera wobbles while standing: same place, other orientation.
  drive.still_when_stopped = false;
  const DrivePath wobbling(world, drive, 100.0, 3);
  const double t = wobbling.TimeAtS(stop_s) + 2.0;
  const Rigid3d a = wobbling.CamFromWorld(t), b = wobbling.CamFromWorld(t + 0.5);
  EXPECT_LT((a.Inverse().translation - b.Inverse().translation).norm(), 1e-9);
  EXPECT_GT(RotationDifferenceDeg(a.rotation, b.rotation), 0.01);
}

TEST(DriveVariants, StartFromRestCreepsAndAcceleratesWithinTheLimit) {
  const World world = BareWorld();
  for (const double accel : {1.5, 4.0}) {
    DriveOptions drive = PlainQuery(12.0, 15.0);
    drive.start_from_rest = true;
    drive.max_accel_mps2 = accel;
    const DrivePath path(world, drive, 200.0, 3);
    const std::vector<double> s = FrameS(path);
    const double dt = 1.0 / drive.frame_rate_hz;
    EXPECT_EQ(s[0], 0.0);
    EXPECT_LT(s[1] - s[0], 0.2);
    double max_accel = 0;
    int creeping = 0;
    for (size_t i = 1; i + 1 < s.size(); ++i) {
      const double step = s[i] - s[i - 1], next = s[i + 1] - s[i];
      if (step < 0.2) ++creeping;
      max_accel = std::max(max_accel, (next - step) / (dt * dt));
      // Growing until cruising speed (12 m/s = 0.8 m per frame).
      if (next < 0.79) {
        EXPECT_GT(next, step) << "frame " << i;
      }
    }
    std::printf("start from rest, limit %.1f m/s^2: %d frames < 0.2 m, max acceleration %.3f\n",
                accel, creeping, max_accel);
    // Exact up to the frame times' rounding (UNIX seconds: steps of 2.4e-7 s).
    EXPECT_LE(max_accel, accel * 1.001);
    EXPECT_GE(max_accel, accel * 0.95);
    EXPECT_GE(creeping, 1);
  }
  // Creeping: below 0.2 m per frame over the first 10 m, then up to speed.
  DriveOptions drive = PlainQuery(8.0, 15.0);
  drive.start_from_rest = true;
  drive.creep_mps = 1.5;
  drive.creep_m = 10.0;
  const DrivePath path(world, drive, 200.0, 3);
  const std::vector<double> s = FrameS(path);
  int creeping = 0;
  for (size_t i = 1; i < s.size() && s[i] <= 10.0; ++i) {
    EXPECT_LT(s[i] - s[i - 1], 0.2) << "frame " << i;
    ++creeping;
  }
  EXPECT_GE(creeping, static_cast<int>(10.0 / 1.5 * 15.0) - 2);
  EXPECT_NEAR(path.SAt(path.TimeAtS(60.0) + 0.5) - path.SAt(path.TimeAtS(60.0) - 0.5), 8.0, 0.01);
}

TEST(DriveVariants, FastDriveAndStopAtTheEnd) {
  const World world = BareWorld();
  DriveOptions drive = PlainQuery(16.0, 10.0);
  const DrivePath fast(world, drive, 300.0, 3);
  const std::vector<double> s = FrameS(fast);
  double min_step = 1e9;
  for (size_t i = 1; i + 1 < s.size(); ++i) min_step = std::min(min_step, s[i] - s[i - 1]);
  std::printf("fast drive: %zu frames, at least %.3f m per frame\n", s.size(), min_step);
  EXPECT_GE(min_step, 1.5);

  drive = PlainQuery(10.0, 10.0);
  drive.end_stop_s = 3.0;
  drive.still_when_stopped = true;
  const DrivePath stopping(world, drive, 150.0, 3);
  const std::vector<double> times = stopping.FrameTimes();
  const size_t n = times.size();
  int repeated = 0;
  for (size_t i = n - 1;
       i > 0 && SamePose(stopping.CamFromWorld(times[i]), stopping.CamFromWorld(times[i - 1]));
       --i) {
    ++repeated;
  }
  EXPECT_GE(repeated, 29);  // 3 s at 10 Hz
  EXPECT_NEAR(stopping.SAt(times.back()), 150.0, 1e-9);
  // Braking within the limit: the last second before the stand covers a^2/2 at most.
  const double t_stop = stopping.TimeAtS(150.0);
  EXPECT_LE(150.0 - stopping.SAt(t_stop - 1.0), 0.5 * drive.max_accel_mps2 * 1.02);
}

TEST(DriveVariants, QueryBeyondTheSurveyedStretch) {
  const World world = BareWorld();
  DriveOptions drive = PlainQuery(8.0, 5.0);
  drive.start_offset_m = -20.0;
  drive.end_offset_m = -35.0;
  const DrivePath path(world, drive, 100.0, 3);
  const EnuFrame frame(world.origin());
  const PositionTrack truth = GroundTruthTrack(path, frame, path.FrameTimes());
  double min_s = 1e9, max_s = -1e9;
  for (const PositionSample& sample : truth.samples) {
    const double s = world.centreline.ToRoad(frame.ToEnu(sample.position).head<2>()).s_m;
    min_s = std::min(min_s, s);
    max_s = std::max(max_s, s);
  }
  std::printf("query ground truth s in [%.2f, %.2f] m, survey [0, 100] m\n", min_s, max_s);
  EXPECT_NEAR(min_s, -20.0, 1e-6);
  EXPECT_GT(max_s, 135.0 - 8.0 / 5.0);  // within a frame of the end
  EXPECT_LE(max_s, 135.0 + 1e-6);
  // Bounded by the world's margins.
  SynthOptions options;
  options.length_m = 100;
  options.query.start_offset_m = -options.world.margin_before_m - 1;
  EXPECT_THROW(options.Check(), Error);
  options.query.start_offset_m = -options.world.margin_before_m;
  options.query.end_offset_m = 40.0 - options.world.margin_after_m - 1;
  EXPECT_THROW(options.Check(), Error);
  options.query.end_offset_m = 40.0 - options.world.margin_after_m;
  EXPECT_NO_THROW(options.Check());
}

TEST(DriveVariants, QueryTakesCurvesOnAnotherLine) {
  const World world = BareWorld();
  DriveOptions survey = PlainQuery(8.0, 10.0), query = PlainQuery(6.0, 15.0);
  survey.lateral_offset_m = query.lateral_offset_m = 0.0;
  query.curve_cut_m = 1.3;
  const DrivePath survey_path(world, survey, 250.0, 1), query_path(world, query, 250.0, 2);
  double max_curve = 0, max_straight = 0;
  for (const double t : query_path.FrameTimes()) {
    const Eigen::Vector3d centre = query_path.CamFromWorld(t).Inverse().translation;
    const RoadCoordinates rc = world.centreline.ToRoad(centre.head<2>());
    // The survey's line at the same s.
    const Eigen::Vector3d survey_centre =
        survey_path.CamFromWorld(survey_path.TimeAtS(rc.s_m)).Inverse().translation;
    const double difference = rc.d_m - world.centreline.ToRoad(survey_centre.head<2>()).d_m;
    const int piece = world.centreline.PieceAt(rc.s_m);
    const double k = world.centreline.pieces()[piece].curvature_per_m;
    if (k == 0) {
      max_straight = std::max(max_straight, std::abs(difference));
    } else {
      max_curve = std::max(max_curve, std::abs(difference));
      EXPECT_GE(difference * k, -1e-9);  // towards the inside
    }
  }
  std::printf("line: differs by up to %.3f m in curves, %.1e m on straights\n", max_curve,
              max_straight);
  EXPECT_NEAR(max_curve, 1.3, 0.01);
  EXPECT_LT(max_straight, 1e-6);
}

TEST(DriveVariants, OptionsAreChecked) {
  DriveOptions drive = DriveOptions::Query();
  drive.curve_cut_m = 2.5;
  EXPECT_THROW(drive.Check("q"), Error);
  drive = DriveOptions::Query();
  drive.turn_radius_m = 3;
  EXPECT_THROW(drive.Check("q"), Error);
  drive = DriveOptions::Query();
  drive.jpeg_quality = 101;
  EXPECT_THROW(drive.Check("q"), Error);
  drive = DriveOptions::Query();
  drive.creep_mps = -1;
  EXPECT_THROW(drive.Check("q"), Error);
  // A turn in needs a side street.
  drive = DriveOptions::Query();
  drive.turn_in = true;
  EXPECT_THROW(DrivePath(BareWorld(), drive, 100.0, 1), Error);
  SynthOptions options;
  options.query.turn_in = true;
  EXPECT_THROW(options.Check(), Error);
}

}  // namespace
}  // namespace epiloc
