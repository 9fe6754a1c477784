// Where the localizer's frames come from: a recorded drive directory, a drive directory that is
// still growing (a recorder writing it), or a video file / camera with optional GNSS.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>

#include "epiloc/camera/camera.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/drive_follower.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/localize/localizer.h"

namespace epiloc {

// Seconds on the steady clock: the clock of QueryFrame::arrival_s (latency is measured on it).
double SteadyNowSeconds();

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Calibration of the frames as delivered.
  virtual const Camera& camera() const = 0;
  // The next frame, waiting for it if the source is live; none at the end of the input. Throws
  // Error for an unreadable frame.
  virtual std::optional<QueryFrame> Next() = 0;
  // Live sources: notes the frames that have arrived since the last call, with their arrival
  // time, without reading them (LocalizeStream calls it while its queue is full, so that a
  // frame's latency counts from its arrival, not from when there was room for it).
  virtual void Poll() {}
  // Live sources: when the next frame arrived `max_age_s` or more ago and a newer one has
  // arrived too, drops it unread and returns its frame number, time, arrival and GNSS (no image):
  // a frame that late is skipped before its extraction costs time. Else none.
  virtual std::optional<QueryFrame> SkipStale(double /*max_age_s*/) { return std::nullopt; }
  // Live sources: frames that have arrived (seen by the last poll) and not been delivered yet.
  virtual int NumArrived() const { return 0; }
  // Number of frames when known in advance (progress), else -1.
  virtual int64_t size() const { return -1; }
  // Name for messages (the drive directory, the video).
  virtual std::string name() const = 0;
};

// A recorded drive directory: every frame in order, each with its GNSS position interpolated
// from the drive's GNSS (PositionFrames; none without GNSS or with `use_gnss` false).
class DriveFrameSource : public FrameSource {
 public:
  DriveFrameSource(const std::string& drive_dir, bool use_gnss);
  const Camera& camera() const override { return drive_.camera; }
  std::optional<QueryFrame> Next() override;
  int64_t size() const override { return static_cast<int64_t>(drive_.frames.size()); }
  std::string name() const override { return drive_.dir; }
  const Drive& drive() const { return drive_; }

 private:
  Drive drive_;
  FramePositions gnss_;
  std::unique_ptr<FrameReader> reader_;
  size_t next_ = 0;
};

// A drive directory another program is still writing (DriveFollower): frames are delivered as
// their rows appear in the frames CSV, with the GNSS position at their time from the samples
// received so far; the input ends after `idle_timeout_s` without a new frame. The constructor
// waits up to `idle_timeout_s` for the manifest (drive.json) to appear.
class FollowDriveSource : public FrameSource {
 public:
  // `poll_interval_s`: how often the files are checked for new rows.
  FollowDriveSource(const std::string& drive_dir,
                    bool use_gnss,
                    double idle_timeout_s,
                    double poll_interval_s = 0.005);
  const Camera& camera() const override { return follower_.manifest().camera; }
  std::optional<QueryFrame> Next() override;
  void Poll() override;
  std::optional<QueryFrame> SkipStale(double max_age_s) override;
  int NumArrived() const override { return static_cast<int>(pending_.size()); }
  std::string name() const override { return follower_.manifest().dir; }

 private:
  // A row seen in the frames CSV, not delivered yet, and when the poll saw it (its arrival:
  // latency counts from it).
  struct Pending {
    FrameRecord record;
    double arrival_s = 0.0;
  };
  // The frame without its image: number, time, arrival, where, GNSS.
  QueryFrame Header(const Pending& pending);

  DriveFollower follower_;
  bool use_gnss_;
  double idle_timeout_s_;
  double poll_interval_s_;
  std::deque<Pending> pending_;
};

struct VideoSourceOptions {
  // UNIX time of the video's first frame (a file's frame times are this plus its position);
  // a camera device's frames get the wall-clock time instead. Default (none): 0 for a file.
  std::optional<double> start_time_s;
  // GNSS for the frames (none: no prior), e.g. ReadPositions of a CSV or NMEA log.
  PositionTrack gnss;
  double max_gap_s = 1.5;   // a frame farther than this from every GNSS sample has no prior
  int64_t max_frames = -1;  // stop after this many frames (-1 = the whole video)
};

// A video file or camera (OpenCV VideoCapture: a path, or a device number such as "0").
class VideoFrameSource : public FrameSource {
 public:
  VideoFrameSource(const std::string& video, const Camera& camera, VideoSourceOptions options);
  ~VideoFrameSource() override;
  const Camera& camera() const override { return camera_; }
  std::optional<QueryFrame> Next() override;
  int64_t size() const override { return num_frames_; }
  std::string name() const override { return video_; }

 private:
  struct Capture;
  std::string video_;
  Camera camera_;
  VideoSourceOptions options_;
  std::unique_ptr<Capture> capture_;
  bool device_ = false;
  int64_t num_frames_ = -1;
  frame_t next_frame_ = 0;
};

}  // namespace epiloc
