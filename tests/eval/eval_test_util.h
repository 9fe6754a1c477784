// Helpers of the eval tests: a temporary directory, text files, error expectations, a tiny KITTI
// tree, and results built from ENU positions.
#pragma once

#include <unistd.h>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "epiloc/core/error.h"
#include "epiloc/geo/geodetic.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/result.h"
#include "test_util.h"

namespace epiloc {

// The origin of the synthetic tests.
inline Geodetic TestOrigin() { return {49.0, 8.4, 100.0}; }

// A track of `points` (ENU about TestOrigin()) at times `times`, with frame numbers 0, 1, ... when
// `with_frames`.
inline PositionTrack TrackFromEnu(const std::vector<Eigen::Vector3d>& points,
                                  const std::vector<double>& times,
                                  bool with_frames) {
  const EnuFrame enu(TestOrigin());
  PositionTrack track;
  track.source = "synthetic_truth";
  for (size_t i = 0; i < points.size(); ++i) {
    PositionSample sample;
    sample.timestamp_s = times[i];
    sample.position = enu.ToGeodetic(points[i]);
    if (with_frames) sample.frame = static_cast<frame_t>(i);
    track.samples.push_back(sample);
  }
  return track;
}

// An ok result row at ENU `point` about TestOrigin().
inline ResultRow OkRow(const std::string& method,
                       frame_t frame,
                       double timestamp_s,
                       const Eigen::Vector3d& point) {
  ResultRow row;
  row.method = method;
  row.frame = frame;
  row.timestamp_s = timestamp_s;
  row.position = EnuFrame(TestOrigin()).ToGeodetic(point);
  row.has_position = true;
  row.status = ResultStatus::kOk;
  return row;
}

inline ResultRow StatusRow(const std::string& method,
                           frame_t frame,
                           double timestamp_s,
                           ResultStatus status) {
  ResultRow row;
  row.method = method;
  row.frame = frame;
  row.timestamp_s = timestamp_s;
  row.status = status;
  return row;
}

// A tiny KITTI raw tree under `root` (identity calibration: IMU = camera 0 axes, 40x30 images)
// with `frames` OXTS records heading north (yaw 90 deg), 1e-5 deg latitude (~1.11 m) apart,
// 0.1 s apart; images 5 ms after the OXTS records. Returns the drive folder.
inline std::string WriteMiniKitti(const std::string& root, int frames) {
  const std::string identity = "1 0 0 0 1 0 0 0 1";
  WriteText(root + "/calib_cam_to_cam.txt",
            "calib_time: 09-Jan-2012 13:57:47\nR_rect_00: " + identity +
                "\nS_rect_00: 40 30\nP_rect_00: 40 0 19.5 0 0 40 14.5 0 0 0 1 0\n");
  WriteText(root + "/calib_velo_to_cam.txt", "R: " + identity + "\nT: 0 0 0\n");
  WriteText(root + "/calib_imu_to_velo.txt", "R: " + identity + "\nT: 0 0 0\n");
  const std::string drive = root + "/2011_09_26_drive_0001_sync";
  std::string times, oxts_times;
  for (int i = 0; i < frames; ++i) {
    const std::string image = fmt::format("{}/image_00/data/{:010d}.png", drive, i);
    std::filesystem::create_directories(std::filesystem::path(image).parent_path());
    cv::imwrite(image, cv::Mat(30, 40, CV_8UC1, cv::Scalar(i * 10)));
    std::string values = fmt::format("{} 8.4 100 0 0 {}", 49.0 + i * 1e-5, M_PI / 2);
    for (int k = 6; k < 30; ++k) values += " 0";
    WriteText(fmt::format("{}/oxts/data/{:010d}.txt", drive, i), values);
    times += fmt::format("2011-09-26 13:04:32.{:09d}\n", 100000000 * i + 5000000);
    oxts_times += fmt::format("2011-09-26 13:04:32.{:09d}\n", 100000000 * i);
  }
  WriteText(drive + "/image_00/timestamps.txt", times);
  WriteText(drive + "/oxts/timestamps.txt", oxts_times);
  return drive;
}

}  // namespace epiloc
