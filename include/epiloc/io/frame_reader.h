// Reading the frames of a drive as 8-bit images, from image files or a video.
#pragma once

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include "epiloc/camera/camera.h"
#include "epiloc/io/drive.h"

namespace epiloc {

// Reads frames by their index into drive.frames. Copies what it needs from the drive (keeps no
// reference to it). Thread-safe: image files are read concurrently; a video is decoded
// sequentially under a mutex, seeking only when the index goes backwards or jumps more than
// kMaxVideoSkip frames ahead, so reading in order decodes each frame once.
//
// PNG and JPEG, grey or colour, 8 or 16 bit (16-bit values are scaled to 8 bit by 1/256) are
// accepted; pixels are read as stored (no EXIF rotation). Errors name the frames CSV line of a
// frame listed there, "<frames.csv>:<line>: image <name as listed>: <problem>", else the image
// file, "<path>: <problem>"; problems: "image file not found", "cannot decode (truncated PNG:
// ...)", "cannot decode (not a PNG or JPEG, or corrupt)", "image size WxH differs from the
// calibration's WxH", ...
class FrameReader {
 public:
  static constexpr int64_t kMaxVideoSkip = 30;

  explicit FrameReader(const Drive& drive);
  FrameReader(const FrameReader&) = delete;
  FrameReader& operator=(const FrameReader&) = delete;

  size_t size() const { return frames_.size(); }

  // CV_8UC1 image of frame `index` (colour converted to grey). Throws Error for an index out of
  // range and the failures above.
  cv::Mat ReadGrey(size_t index) const;
  // CV_8UC3 BGR image of frame `index` (grey replicated into three channels).
  cv::Mat ReadColour(size_t index) const;

  // FrameContentHash of frame `index`; for a video the hash of the video file is computed once.
  std::string ContentHash(size_t index) const;

 private:
  cv::Mat Read(size_t index, bool colour) const;
  cv::Mat ReadVideoFrame(frame_t frame) const;

  std::string dir_;
  Camera camera_;
  std::vector<FrameRecord> frames_;
  std::string video_path_;
  std::string frames_csv_;

  mutable std::mutex video_mutex_;  // guards the members below
  mutable cv::VideoCapture capture_;
  mutable frame_t next_video_frame_ = 0;  // frame the next grab() returns
  mutable std::string video_hash_;
};

// Content hash (epiloc::HashFile, 32 hex digits) of frame `index`'s image file; for a video frame,
// the hash of "<hash of the video file>:<frame number>". Throws Error if the file cannot be read.
std::string FrameContentHash(const Drive& drive, size_t index);

// One image file as FrameReader reads it: 8-bit, grey (CV_8UC1) or BGR (`colour`), checked
// against the calibration's size. Throws Error "<path>: <problem>" with the problems of
// FrameReader; a truncated PNG or JPEG is reported without handing it to the decoder (whose
// libraries print on stderr).
cv::Mat ReadImageFile(const std::string& path, const Camera& camera, bool colour);

// The image of one frame of a drive's image files (e.g. a frame polled from a growing drive), as
// FrameReader reads it, with its errors naming the frames CSV line.
cv::Mat ReadFrameImage(const Drive& drive, const FrameRecord& frame, bool colour);

// "" if `data` (the bytes of an image file) is a complete PNG or JPEG or another format; else why
// not: "truncated PNG: chunk IDAT ends past the end of the file", "truncated JPEG: no
// end-of-image marker", ...
std::string ImageTruncation(const std::string& data);

// Silences the libraries' own logging on stderr (OpenCV's log, FFmpeg's through OpenCV) so that
// an error is the one line of its epiloc::Error. Call before the first video is opened.
void QuietLibraryLogging();

// Throws Error "<path>: image size WxH differs from the calibration's WxH" unless `image` has the
// camera's size.
void CheckImageSize(const cv::Mat& image, const Camera& camera, const std::string& path);

}  // namespace epiloc
