// ASPRS LAS 1.0-1.4, uncompressed point data formats 0-10 (read only). Written from the
// specification (LAS 1.4 R15, tables 3 and 7-17): Debian has no LAS library (liblas, PDAL and
// LASzip are not packaged for bookworm), and uncompressed LAS is a fixed binary layout.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "cloud_io_internal.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace cloud_internal {
namespace {

constexpr size_t kLegacyHeaderBytes = 227;  // LAS 1.0-1.2 public header
constexpr size_t kLas14HeaderBytes = 375;

// Minimum record bytes and the offset of the colour (0: none) per point data format 0-10.
struct LasPointFormat {
  size_t record_bytes;
  size_t rgb_offset;
};
constexpr LasPointFormat kLasFormats[] = {{20, 0}, {28, 0},  {26, 20}, {34, 28}, {57, 0}, {63, 28},
                                          {30, 0}, {36, 30}, {38, 30}, {59, 0},  {67, 30}};

class LasSource : public PointSource {
 public:
  LasSource(const std::string& path, const CloudReadOptions& options) : PointSource(path, options) {
    OpenForReading(path, &in_);
    std::vector<char> header(kLas14HeaderBytes, 0);
    in_.read(header.data(), static_cast<std::streamsize>(header.size()));
    const auto got = static_cast<size_t>(in_.gcount());
    in_.clear();
    if (got < 4 || std::string(header.data(), 4) != "LASF") {
      Throw("{}: not a LAS file (no 'LASF' signature)", path);
    }
    EPILOC_CHECK(got >= kLegacyHeaderBytes, "{}: truncated LAS header", path);
    const bool swap = !HostIsLittleEndian();
    auto u8 = [&](size_t at) { return static_cast<uint8_t>(header[at]); };
    auto u16 = [&](size_t at) {
      return static_cast<size_t>(LoadScalar(&header[at], ScalarType::kUint16, swap));
    };
    auto u32 = [&](size_t at) {
      return static_cast<uint64_t>(LoadScalar(&header[at], ScalarType::kUint32, swap));
    };
    auto f64 = [&](size_t at) { return LoadScalar(&header[at], ScalarType::kFloat64, swap); };
    const int major = u8(24);
    const int minor = u8(25);
    EPILOC_CHECK(major == 1 && minor <= 4, "{}: unsupported LAS version {}.{}", path, major, minor);
    const size_t header_bytes = u16(94);
    const uint64_t point_offset = u32(96);
    const int format_id = u8(104);
    const size_t record_bytes = u16(105);
    if ((format_id & 0xc0) != 0) {
      Throw(
          "{}: a LAZ (compressed LAS) file; epiloc reads uncompressed LAS only: decompress it "
          "first (with LAStools' laszip or PDAL, to .las or .ply)",
          path);
    }
    EPILOC_CHECK(format_id <= 10, "{}: unknown LAS point data format {}", path, format_id);
    const LasPointFormat format = kLasFormats[format_id];
    EPILOC_CHECK(record_bytes >= format.record_bytes,
                 "{}: LAS point format {} records need {} bytes, the header says {}", path,
                 format_id, format.record_bytes, record_bytes);
    // Checked as read (a double), before the conversion: a 64-bit count beyond int64 is
    // undefined behaviour to convert (found by the cloud fuzz harness).
    double count = static_cast<double>(u32(107));
    if (minor >= 4 && header_bytes >= kLas14HeaderBytes && got >= kLas14HeaderBytes) {
      count = LoadScalar(&header[247], ScalarType::kUint64, swap);
    }
    EPILOC_CHECK(count >= 0 && count <= static_cast<double>(kMaxPointsPerFile),
                 "{}: corrupt LAS header: {:.0f} points", path, count);
    const int64_t num_points = static_cast<int64_t>(count);
    const uint64_t file_bytes = std::filesystem::file_size(path);
    EPILOC_CHECK(point_offset >= kLegacyHeaderBytes && point_offset <= file_bytes,
                 "{}: bad LAS offset to point data {}", path, point_offset);

    info_.format = CloudFormat::kLas;
    info_.encoding = "binary_little_endian";
    info_.num_points = num_points;
    info_.has_intensity = true;
    info_.has_colour = format.rgb_offset != 0;
    info_.fields = {"X", "Y", "Z", "intensity"};
    if (info_.has_colour) info_.fields.insert(info_.fields.end(), {"red", "green", "blue"});
    info_.bounds.min = Eigen::Vector3f(f64(187), f64(203), f64(219));
    info_.bounds.max = Eigen::Vector3f(f64(179), f64(195), f64(211));

    layout_.swap = swap;
    const double scale[3] = {f64(131), f64(139), f64(147)};
    const double shift[3] = {f64(155), f64(163), f64(171)};
    FieldSlot* axes[3] = {&layout_.x, &layout_.y, &layout_.z};
    for (int k = 0; k < 3; ++k) {
      EPILOC_CHECK(scale[k] != 0.0 && std::isfinite(scale[k]) && std::isfinite(shift[k]),
                   "{}: bad LAS scale factor {} or offset {}", path, scale[k], shift[k]);
      *axes[k] = FieldSlot{ScalarType::kInt32, 4 * static_cast<size_t>(k), 0, scale[k], shift[k]};
    }
    layout_.intensity = FieldSlot{ScalarType::kUint16, 12};
    if (info_.has_colour) {
      layout_.red = FieldSlot{ScalarType::kUint16, format.rgb_offset};
      layout_.green = FieldSlot{ScalarType::kUint16, format.rgb_offset + 2};
      layout_.blue = FieldSlot{ScalarType::kUint16, format.rgb_offset + 4};
    }
    record_bytes_ = record_bytes;
    layout_.SetStride(record_bytes_);
    CheckBinaryBody(num_points, point_offset, record_bytes_);
    in_.seekg(static_cast<std::streamoff>(point_offset));
  }

  int64_t Read(int64_t max_records, PointCloud* out) override {
    const int64_t n = std::min(max_records, info_.num_points - done_);
    constexpr int64_t kBlock = 1 << 16;
    for (int64_t begin = 0; begin < n; begin += kBlock) {
      const int64_t count = std::min(kBlock, n - begin);
      ReadBody(&in_, static_cast<size_t>(count) * record_bytes_, record_bytes_, done_,
               info_.num_points, &buffer_);
      DecodeRecords(buffer_.data(), 0, count, layout_, out);
      done_ += count;
    }
    return std::max<int64_t>(n, 0);
  }

 private:
  std::ifstream in_;
  RecordLayout layout_;
  size_t record_bytes_ = 0;
  int64_t done_ = 0;
  std::vector<char> buffer_;
};

}  // namespace

std::unique_ptr<PointSource> OpenLasSource(const std::string& path,
                                           const CloudReadOptions& options) {
  return std::make_unique<LasSource>(path, options);
}

}  // namespace cloud_internal
}  // namespace epiloc
