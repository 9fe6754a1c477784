#include "epiloc/localize/frame_source.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <thread>

#include <opencv2/videoio.hpp>

#include "epiloc/core/error.h"

namespace epiloc {
namespace {

using Clock = std::chrono::steady_clock;

// A drive being recorded may not have its manifest yet when the follower starts (the recorder
// starting a moment later): it waits for drive.json up to `timeout_s`, then lets the follower
// report it missing. Returns `drive_dir`.
const std::string& AwaitManifest(const std::string& drive_dir,
                                 double timeout_s,
                                 double poll_interval_s) {
  const std::filesystem::path manifest = std::filesystem::path(drive_dir) / "drive.json";
  const auto start = Clock::now();
  std::error_code error;
  while (!(std::filesystem::is_regular_file(manifest, error) &&
           std::filesystem::file_size(manifest, error) > 0) &&
         std::chrono::duration<double>(Clock::now() - start).count() < timeout_s) {
    std::this_thread::sleep_for(std::chrono::duration<double>(std::max(poll_interval_s, 0.01)));
  }
  return drive_dir;
}

bool IsDeviceNumber(const std::string& text) {
  return !text.empty() && text.size() < 4 &&
         std::all_of(text.begin(), text.end(), [](char c) { return std::isdigit(c) != 0; });
}

}  // namespace

double SteadyNowSeconds() {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

DriveFrameSource::DriveFrameSource(const std::string& drive_dir, bool use_gnss)
    : drive_(LoadDrive(drive_dir)) {
  if (use_gnss) {
    EPILOC_CHECK(!drive_.gnss.samples.empty(),
                 "{}: the drive has no GNSS positions (use --no-gps to localize without)",
                 drive_.dir);
    gnss_ = PositionFrames(drive_, drive_.gnss);
  }
  reader_ = std::make_unique<FrameReader>(drive_);
}

std::optional<QueryFrame> DriveFrameSource::Next() {
  if (next_ >= drive_.frames.size()) return std::nullopt;
  const size_t i = next_++;
  QueryFrame frame;
  frame.frame = drive_.frames[i].frame;
  frame.timestamp_s = drive_.frames[i].timestamp_s;
  frame.arrival_s = SteadyNowSeconds();
  frame.where = drive_.FrameWhere(drive_.frames[i]);
  // The localizer works on grey images: reading them grey spares a colour conversion later.
  frame.image = reader_->ReadGrey(i);
  frame.read_seconds = SteadyNowSeconds() - frame.arrival_s;
  if (!gnss_.per_frame.empty() && gnss_.per_frame[i]) frame.gnss = gnss_.per_frame[i]->position;
  return frame;
}

FollowDriveSource::FollowDriveSource(const std::string& drive_dir,
                                     bool use_gnss,
                                     double idle_timeout_s,
                                     double poll_interval_s)
    : follower_(AwaitManifest(drive_dir, idle_timeout_s, poll_interval_s)),
      use_gnss_(use_gnss),
      idle_timeout_s_(idle_timeout_s),
      poll_interval_s_(poll_interval_s) {
  EPILOC_CHECK(idle_timeout_s > 0, "--idle-timeout-s must be positive");
  EPILOC_CHECK(poll_interval_s > 0, "follow: the poll interval must be positive");
  EPILOC_CHECK(!use_gnss || follower_.has_gnss(),
               "{}: the drive has no GNSS file (use --no-gps to localize without)", drive_dir);
}

void FollowDriveSource::Poll() {
  // Rows read in one poll arrived together, however long the earlier ones of them take.
  const double now = SteadyNowSeconds();
  for (FrameRecord& record : follower_.PollFrames()) pending_.push_back({std::move(record), now});
}

QueryFrame FollowDriveSource::Header(const Pending& pending) {
  QueryFrame frame;
  frame.frame = pending.record.frame;
  frame.timestamp_s = pending.record.timestamp_s;
  frame.arrival_s = pending.arrival_s;
  frame.where = follower_.manifest().FrameWhere(pending.record);
  if (use_gnss_) {
    if (const std::optional<PositionSample> fix = follower_.GnssAt(pending.record.timestamp_s)) {
      frame.gnss = fix->position;
    }
  }
  return frame;
}

std::optional<QueryFrame> FollowDriveSource::SkipStale(double max_age_s) {
  Poll();
  if (pending_.size() < 2 || SteadyNowSeconds() - pending_.front().arrival_s < max_age_s) {
    return std::nullopt;
  }
  QueryFrame frame = Header(pending_.front());
  pending_.pop_front();
  return frame;
}

std::optional<QueryFrame> FollowDriveSource::Next() {
  const auto idle_since = Clock::now();
  for (;;) {
    Poll();
    if (!pending_.empty()) break;
    if (std::chrono::duration<double>(Clock::now() - idle_since).count() > idle_timeout_s_) {
      return std::nullopt;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(poll_interval_s_));
  }
  const Pending pending = std::move(pending_.front());
  pending_.pop_front();
  QueryFrame frame = Header(pending);
  const double read_start = SteadyNowSeconds();
  frame.image = ReadFrameImage(follower_.manifest(), pending.record, false);
  frame.read_seconds = SteadyNowSeconds() - read_start;
  return frame;
}

struct VideoFrameSource::Capture {
  cv::VideoCapture capture;
};

VideoFrameSource::VideoFrameSource(const std::string& video,
                                   const Camera& camera,
                                   VideoSourceOptions options)
    : video_(video),
      camera_(camera),
      options_(std::move(options)),
      capture_(std::make_unique<Capture>()) {
  camera_.Check(video + ": calibration");
  device_ = IsDeviceNumber(video);
  const bool opened =
      device_ ? capture_->capture.open(std::stoi(video)) : capture_->capture.open(video);
  if (!opened) Throw("{}: cannot open {}", video, device_ ? "the camera" : "the video");
  if (!device_) {
    const double count = capture_->capture.get(cv::CAP_PROP_FRAME_COUNT);
    if (count > 0) num_frames_ = static_cast<int64_t>(count);
    if (options_.max_frames >= 0 && (num_frames_ < 0 || options_.max_frames < num_frames_)) {
      num_frames_ = options_.max_frames;
    }
  }
}

VideoFrameSource::~VideoFrameSource() = default;

std::optional<QueryFrame> VideoFrameSource::Next() {
  if (options_.max_frames >= 0 && next_frame_ >= options_.max_frames) return std::nullopt;
  QueryFrame frame;
  const double read_start = SteadyNowSeconds();
  if (!capture_->capture.read(frame.image) || frame.image.empty()) return std::nullopt;
  frame.arrival_s = SteadyNowSeconds();
  frame.read_seconds = frame.arrival_s - read_start;
  frame.frame = next_frame_++;
  if (device_) {
    frame.timestamp_s =
        std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  } else {
    frame.timestamp_s =
        options_.start_time_s.value_or(0.0) + capture_->capture.get(cv::CAP_PROP_POS_MSEC) / 1000.0;
  }
  // Messages about the frame (a featureless image, a wrong size) name the video and the frame's
  // index in it, as a drive's frames name their frames CSV line.
  frame.where = fmt::format("{}{} frame {}", device_ ? "camera " : "", video_, frame.frame);
  CheckImageSize(frame.image, camera_, frame.where);
  if (!options_.gnss.samples.empty()) {
    if (const auto fix = options_.gnss.Interpolate(frame.timestamp_s, options_.max_gap_s)) {
      frame.gnss = fix->position;
    }
  }
  return frame;
}

}  // namespace epiloc
