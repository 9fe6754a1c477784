#include "epiloc/io/frame_reader.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "epiloc/core/hash.h"
#include "io_internal.h"

namespace epiloc {
namespace {

cv::Mat ToEightBit(const cv::Mat& image) {
  if (image.depth() == CV_8U) return image;
  cv::Mat converted;
  image.convertTo(converted, CV_8U, image.depth() == CV_16U ? 1.0 / 256.0 : 1.0);
  return converted;
}

cv::Mat ConvertChannels(const cv::Mat& image, bool colour) {
  cv::Mat out;
  switch (image.channels()) {
    case 1:
      if (!colour) return image;
      cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
      return out;
    case 3:
      if (colour) return image;
      cv::cvtColor(image, out, cv::COLOR_BGR2GRAY);
      return out;
    case 4:
      cv::cvtColor(image, out, colour ? cv::COLOR_BGRA2BGR : cv::COLOR_BGRA2GRAY);
      return out;
    default:
      return cv::Mat();
  }
}

std::string VideoFrameHash(const std::string& video_hash, frame_t frame) {
  const std::string text = video_hash + ":" + std::to_string(frame);
  return HashBytes(text.data(), text.size());
}

}  // namespace

void CheckImageSize(const cv::Mat& image, const Camera& camera, const std::string& path) {
  if (image.cols != camera.width || image.rows != camera.height) {
    Throw("{}: image size {}x{} differs from the calibration's {}x{}", path, image.cols, image.rows,
          camera.width, camera.height);
  }
}

cv::Mat ReadImageFile(const std::string& path, const Camera& camera, bool colour) {
  // IMREAD_UNCHANGED keeps 16-bit data, so the conversion below is ours and explicit.
  cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (image.empty()) Throw("{}: cannot read image", path);
  CheckImageSize(image, camera, path);
  image = ConvertChannels(ToEightBit(image), colour);
  if (image.empty()) Throw("{}: unsupported number of image channels", path);
  return image;
}

FrameReader::FrameReader(const Drive& drive)
    : dir_(drive.dir),
      camera_(drive.camera),
      frames_(drive.frames),
      video_path_(drive.VideoPath()) {}

cv::Mat FrameReader::ReadGrey(size_t index) const { return Read(index, false); }

cv::Mat FrameReader::ReadColour(size_t index) const { return Read(index, true); }

cv::Mat FrameReader::Read(size_t index, bool colour) const {
  if (index >= frames_.size()) {
    Throw("frame index {} out of range (the drive has {} frames)", index, frames_.size());
  }
  if (video_path_.empty()) {
    return ReadImageFile(ResolvePath(dir_, frames_[index].image), camera_, colour);
  }
  const std::string& path = video_path_;
  cv::Mat image = ReadVideoFrame(frames_[index].frame);
  CheckImageSize(image, camera_, path);
  image = ConvertChannels(ToEightBit(image), colour);
  if (image.empty()) Throw("{}: unsupported number of image channels", path);
  return image;
}

cv::Mat FrameReader::ReadVideoFrame(frame_t frame) const {
  std::lock_guard<std::mutex> lock(video_mutex_);
  if (!capture_.isOpened()) {
    if (!capture_.open(video_path_)) Throw("{}: cannot open video", video_path_);
    next_video_frame_ = 0;
  }
  if (frame < next_video_frame_ || frame > next_video_frame_ + kMaxVideoSkip) {
    capture_.set(cv::CAP_PROP_POS_FRAMES, static_cast<double>(frame));
    next_video_frame_ = frame;
  }
  while (next_video_frame_ < frame) {
    if (!capture_.grab()) Throw("{}: cannot read frame {}", video_path_, next_video_frame_);
    ++next_video_frame_;
  }
  cv::Mat image;
  if (!capture_.read(image) || image.empty()) {
    // Force a seek next time: the decoder's position is unknown after a failure.
    next_video_frame_ = -kMaxVideoSkip - 2;
    Throw("{}: cannot read frame {}", video_path_, frame);
  }
  ++next_video_frame_;
  return image;
}

std::string FrameReader::ContentHash(size_t index) const {
  if (index >= frames_.size()) {
    Throw("frame index {} out of range (the drive has {} frames)", index, frames_.size());
  }
  if (video_path_.empty()) return HashFile(ResolvePath(dir_, frames_[index].image));
  std::lock_guard<std::mutex> lock(video_mutex_);
  if (video_hash_.empty()) video_hash_ = HashFile(video_path_);
  return VideoFrameHash(video_hash_, frames_[index].frame);
}

std::string FrameContentHash(const Drive& drive, size_t index) {
  if (index >= drive.frames.size()) {
    Throw("frame index {} out of range (the drive has {} frames)", index, drive.frames.size());
  }
  if (drive.video.empty()) return HashFile(drive.ImagePath(drive.frames[index]));
  return VideoFrameHash(HashFile(drive.VideoPath()), drive.frames[index].frame);
}

}  // namespace epiloc
