#include "epiloc/io/frame_reader.h"

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <opencv2/core/utils/logger.hpp>
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

std::string SizeProblem(const cv::Mat& image, const Camera& camera) {
  if (image.cols == camera.width && image.rows == camera.height) return "";
  return fmt::format("image size {}x{} differs from the calibration's {}x{}", image.cols,
                     image.rows, camera.width, camera.height);
}

// The image at `path` as ReadImageFile returns it, or an empty image and *problem set to what is
// wrong ("image file not found", "cannot decode (truncated PNG: ...)", ...).
cv::Mat DecodeImageFile(const std::string& path,
                        const Camera& camera,
                        bool colour,
                        std::string* problem) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (!std::filesystem::exists(status)) {
    *problem = "image file not found";
    return cv::Mat();
  }
  if (std::filesystem::is_directory(status)) {
    *problem = "is a folder, not an image file";
    return cv::Mat();
  }
  if (!std::filesystem::is_regular_file(status)) {
    *problem = "not a regular file (a FIFO or device), not an image file";
    return cv::Mat();
  }
  std::string data;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      *problem = "cannot open image file";
      return cv::Mat();
    }
    data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (in.bad()) {
      *problem = "read error";
      return cv::Mat();
    }
  }
  const std::string truncation = ImageTruncation(data);
  if (!truncation.empty()) {
    *problem = fmt::format("cannot decode ({})", truncation);
    return cv::Mat();
  }
  // IMREAD_UNCHANGED keeps 16-bit data, so the conversion below is ours and explicit. A JPEG
  // (always 8-bit) wanted grey is decoded grey: libjpeg then skips the colour planes' inverse DCT,
  // upsampling and colour conversion, half the decoding time of a colour 1080p frame.
  const bool jpeg = data.size() >= 2 && static_cast<uint8_t>(data[0]) == 0xFF &&
                    static_cast<uint8_t>(data[1]) == 0xD8;
  cv::Mat image;
  try {
    image = cv::imdecode(
        cv::Mat(1, static_cast<int>(std::min<size_t>(data.size(), INT32_MAX)), CV_8U, data.data()),
        jpeg && !colour ? cv::IMREAD_GRAYSCALE : cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    // OpenCV refuses a header declaring more than CV_IO_MAX_IMAGE_PIXELS pixels (a 60000x60000
    // PNG of 74 bytes) with an exception whose text names no file: report it as this file's.
    *problem = fmt::format("cannot decode ({})", Printable(e.err));
    return cv::Mat();
  }
  if (image.empty()) {
    *problem = "cannot decode (not a PNG or JPEG, or corrupt)";
    return cv::Mat();
  }
  *problem = SizeProblem(image, camera);
  if (!problem->empty()) return cv::Mat();
  image = ConvertChannels(ToEightBit(image), colour);
  if (image.empty()) *problem = "unsupported number of image channels";
  return image;
}

// Reads a frame's image file; errors name the frames CSV line when `where` is given:
// "<where>: image <name>: <problem>", else "<path>: <problem>".
cv::Mat ReadFrameImageFile(const std::string& path,
                           const std::string& where,
                           const std::string& name,
                           const Camera& camera,
                           bool colour) {
  std::string problem;
  cv::Mat image = DecodeImageFile(path, camera, colour, &problem);
  if (!problem.empty()) {
    if (where.empty()) Throw("{}: {}", path, problem);
    Throw("{}: image {}: {}", where, Printable(name), problem);
  }
  return image;
}

}  // namespace

void CheckImageSize(const cv::Mat& image, const Camera& camera, const std::string& path) {
  const std::string problem = SizeProblem(image, camera);
  if (!problem.empty()) Throw("{}: {}", path, problem);
}

std::string ImageTruncation(const std::string& data) {
  static const std::string kPng = "\x89PNG\r\n\x1a\n";
  if (data.compare(0, kPng.size(), kPng) == 0) {
    size_t at = kPng.size();
    while (at + 8 <= data.size()) {
      const auto byte = [&](size_t i) { return static_cast<uint32_t>(static_cast<uint8_t>(data[i])); };
      const uint64_t length = byte(at) << 24 | byte(at + 1) << 16 | byte(at + 2) << 8 | byte(at + 3);
      const std::string type = Printable(data.substr(at + 4, 4));
      if (at + 12 + length > data.size()) {
        return fmt::format("truncated PNG: chunk {} ends past the end of the file", type);
      }
      if (type == "IEND") return "";
      at += 12 + length;
    }
    return "truncated PNG: no IEND chunk";
  }
  if (data.size() >= 2 && static_cast<uint8_t>(data[0]) == 0xFF &&
      static_cast<uint8_t>(data[1]) == 0xD8) {
    // The end-of-image marker, possibly followed by padding some cameras add.
    const size_t end = data.find_last_not_of('\0');
    if (end == std::string::npos || end < 3 || static_cast<uint8_t>(data[end]) != 0xD9 ||
        static_cast<uint8_t>(data[end - 1]) != 0xFF) {
      return "truncated JPEG: no end-of-image marker";
    }
    return "";
  }
  if (data.empty()) return "empty file";
  return "";
}

void QuietLibraryLogging() {
  // Read by OpenCV's FFmpeg backend when it starts: AV_LOG_QUIET. Kept if the user set it.
  ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
}

cv::Mat ReadImageFile(const std::string& path, const Camera& camera, bool colour) {
  return ReadFrameImageFile(path, "", "", camera, colour);
}

cv::Mat ReadFrameImage(const Drive& drive, const FrameRecord& frame, bool colour) {
  return ReadFrameImageFile(drive.ImagePath(frame), drive.FrameWhere(frame), frame.image,
                            drive.camera, colour);
}

FrameReader::FrameReader(const Drive& drive)
    : dir_(drive.dir),
      camera_(drive.camera),
      frames_(drive.frames),
      video_path_(drive.VideoPath()),
      frames_csv_(drive.frames_csv) {}

cv::Mat FrameReader::ReadGrey(size_t index) const { return Read(index, false); }

cv::Mat FrameReader::ReadColour(size_t index) const { return Read(index, true); }

cv::Mat FrameReader::Read(size_t index, bool colour) const {
  if (index >= frames_.size()) {
    Throw("frame index {} out of range (the drive has {} frames)", index, frames_.size());
  }
  if (video_path_.empty()) {
    const FrameRecord& frame = frames_[index];
    const std::string where =
        frames_csv_.empty() || frame.line <= 0 ? "" : Where(frames_csv_, frame.line);
    return ReadFrameImageFile(ResolvePath(dir_, frame.image), where, frame.image, camera_, colour);
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
