// KITTI Velodyne scans (.bin: float32 x y z reflectance) and XYZ text.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iterator>

#include <fmt/format.h>

#include "cloud_io_internal.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"

namespace epiloc {
namespace cloud_internal {
namespace {

constexpr size_t kKittiRecordBytes = 4 * sizeof(float);

class KittiSource : public PointSource {
 public:
  KittiSource(const std::string& path, const CloudReadOptions& options)
      : PointSource(path, options) {
    OpenForReading(path, &in_);
    const uintmax_t bytes = std::filesystem::file_size(path);
    if (bytes % kKittiRecordBytes != 0) {
      Throw(
          "{}: not a KITTI Velodyne scan: {} bytes is not a multiple of 16 (x y z reflectance "
          "as float32)",
          path, bytes);
    }
    info_.format = CloudFormat::kKittiBin;
    info_.encoding = "float32";
    info_.num_points = static_cast<int64_t>(bytes / kKittiRecordBytes);
    info_.has_intensity = true;
    info_.fields = {"x", "y", "z", "reflectance"};
    reserve_hint_ = info_.num_points;
    layout_.swap = !HostIsLittleEndian();
    layout_.x = FieldSlot{ScalarType::kFloat32, 0};
    layout_.y = FieldSlot{ScalarType::kFloat32, 4};
    layout_.z = FieldSlot{ScalarType::kFloat32, 8};
    layout_.intensity = FieldSlot{ScalarType::kFloat32, 12};
    layout_.SetStride(kKittiRecordBytes);
  }

  int64_t Read(int64_t max_records, PointCloud* out) override {
    const int64_t n = std::min(max_records, info_.num_points - done_);
    constexpr int64_t kBlock = 1 << 16;
    for (int64_t begin = 0; begin < n; begin += kBlock) {
      const int64_t count = std::min(kBlock, n - begin);
      ReadBody(&in_, static_cast<size_t>(count) * kKittiRecordBytes, kKittiRecordBytes, done_,
               info_.num_points, &buffer_);
      DecodeRecords(buffer_.data(), 0, count, layout_, out);
      done_ += count;
    }
    return std::max<int64_t>(n, 0);
  }

 private:
  std::ifstream in_;
  RecordLayout layout_;
  int64_t done_ = 0;
  std::vector<char> buffer_;
};

bool IsComment(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t");
  return first == std::string::npos || line[first] == '#' || line.compare(first, 2, "//") == 0;
}

class XyzSource : public PointSource {
 public:
  XyzSource(const std::string& path, const CloudReadOptions& options)
      : PointSource(path, options), reader_(&in_, 1, path) {
    OpenForReading(path, &in_);
    info_.format = CloudFormat::kXyz;
    info_.encoding = "text";
    columns_.fill(-1);
    if (!NextDataLine()) return;  // an empty cloud
    const std::string where = Where(path, reader_.line_number());
    SplitTokens(reader_.line(), true, &tokens_);
    double value = 0;
    const bool header = std::none_of(tokens_.begin(), tokens_.end(),
                                     [&](std::string_view t) { return ParseNumber(t, &value); });
    num_columns_ = tokens_.size();
    if (header) {
      for (size_t k = 0; k < tokens_.size(); ++k) {
        info_.fields.emplace_back(tokens_[k]);
        int& column = columns_[static_cast<size_t>(RoleOfFieldName(info_.fields.back()))];
        if (column < 0) column = static_cast<int>(k);
      }
      for (FieldRole role : {FieldRole::kX, FieldRole::kY, FieldRole::kZ}) {
        EPILOC_CHECK(columns_[static_cast<size_t>(role)] >= 0,
                     "{}: not a point cloud: the column names '{}' lack x, y or z", where,
                     reader_.line());
      }
      pending_ = false;
    } else {
      static const std::vector<std::vector<std::string>> kLayouts = {
          {"x", "y", "z"},
          {"x", "y", "z", "intensity"},
          {"x", "y", "z", "r", "g", "b"},
          {"x", "y", "z", "intensity", "r", "g", "b"}};
      const auto layout = std::find_if(kLayouts.begin(), kLayouts.end(),
                                       [&](const auto& l) { return l.size() == num_columns_; });
      if (layout == kLayouts.end()) {
        Throw(
            "{}: {} columns; XYZ text has 3 (x y z), 4 (x y z intensity), 6 (x y z r g b) or "
            "7 (x y z intensity r g b), or a first line naming the columns",
            where, num_columns_);
      }
      info_.fields = *layout;
      for (size_t k = 0; k < layout->size(); ++k) {
        columns_[static_cast<size_t>(RoleOfFieldName((*layout)[k]))] = static_cast<int>(k);
      }
      pending_ = true;
    }
    info_.has_intensity = column(FieldRole::kIntensity) >= 0;
    info_.has_colour = column(FieldRole::kRed) >= 0 && column(FieldRole::kGreen) >= 0 &&
                       column(FieldRole::kBlue) >= 0;
  }

  int64_t Read(int64_t max_records, PointCloud* out) override {
    int64_t n = 0;
    while (n < max_records && (pending_ || NextDataLine())) {
      pending_ = false;
      ParseLine(out);
      ++n;
    }
    return n;
  }

 private:
  int column(FieldRole role) const { return columns_[static_cast<size_t>(role)]; }

  bool NextDataLine() {
    while (reader_.Next()) {
      if (!IsComment(reader_.line())) return true;
    }
    return false;
  }

  void ParseLine(PointCloud* out) {
    auto where = [&] { return Where(path_, reader_.line_number()); };
    SplitTokens(reader_.line(), true, &tokens_);
    EPILOC_CHECK(tokens_.size() == num_columns_, "{}: {} columns where the file has {}", where(),
                 tokens_.size(), num_columns_);
    auto value = [&](FieldRole role) {
      return ParseNumberOrThrow(tokens_[static_cast<size_t>(column(role))], path_,
                                reader_.line_number());
    };
    float intensity = 0.0f;
    if (with_intensity()) {
      intensity = ConvertIntensity(value(FieldRole::kIntensity), ScalarType::kFloat64,
                                   options_.float_intensity_scale, &stats_);
    }
    std::array<uint8_t, 3> rgb{};
    if (with_colour()) {
      const FieldRole roles[3] = {FieldRole::kRed, FieldRole::kGreen, FieldRole::kBlue};
      for (int c = 0; c < 3; ++c) {
        const double v = value(roles[c]);
        // Guards against reading normals (x y z nx ny nz) as colours.
        EPILOC_CHECK(v >= 0 && v <= 255 && v == std::floor(v),
                     "{}: colour value {} is not an integer in 0..255 (column {})", where(), v,
                     column(roles[c]) + 1);
        rgb[c] = static_cast<uint8_t>(v);
      }
    }
    AddPoint(out, value(FieldRole::kX), value(FieldRole::kY), value(FieldRole::kZ), intensity, rgb);
  }

  std::ifstream in_;
  LineReader reader_;
  size_t num_columns_ = 0;
  std::array<int, 9> columns_{};  // FieldRole -> column index, -1 if absent
  bool pending_ = false;          // the current line is a data line not yet parsed
  std::vector<std::string_view> tokens_;
};

}  // namespace

std::unique_ptr<PointSource> OpenKittiSource(const std::string& path,
                                             const CloudReadOptions& options) {
  return std::make_unique<KittiSource>(path, options);
}

std::unique_ptr<PointSource> OpenXyzSource(const std::string& path,
                                           const CloudReadOptions& options) {
  return std::make_unique<XyzSource>(path, options);
}

void WriteKittiBin(const std::string& path, const PointCloud& cloud) {
  cloud.Check();
  AtomicOfstream file(path, std::ios::binary | std::ios::trunc);
  std::ofstream& out = file.stream();
  constexpr size_t kBlock = 1 << 16;
  std::string buffer;
  for (size_t begin = 0; begin < cloud.size(); begin += kBlock) {
    const size_t end = std::min(cloud.size(), begin + kBlock);
    buffer.clear();
    for (size_t i = begin; i < end; ++i) {
      for (int k = 0; k < 3; ++k) AppendFloatLE(cloud.positions[i][k], &buffer);
      AppendFloatLE(cloud.HasIntensity() ? cloud.intensity[i] : 0.0f, &buffer);
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  }
  file.Commit();
}

void WriteXyz(const std::string& path, const PointCloud& cloud) {
  cloud.Check();
  AtomicOfstream file(path, std::ios::binary | std::ios::trunc);
  std::ofstream& out = file.stream();
  constexpr size_t kBlock = 1 << 16;
  std::string buffer;
  for (size_t begin = 0; begin < cloud.size(); begin += kBlock) {
    const size_t end = std::min(cloud.size(), begin + kBlock);
    buffer.clear();
    auto it = std::back_inserter(buffer);
    for (size_t i = begin; i < end; ++i) {
      const Eigen::Vector3f& p = cloud.positions[i];
      fmt::format_to(it, "{} {} {}", p.x(), p.y(), p.z());
      if (cloud.HasIntensity()) fmt::format_to(it, " {}", cloud.intensity[i]);
      if (cloud.HasColour()) {
        fmt::format_to(it, " {} {} {}", cloud.rgb[i][0], cloud.rgb[i][1], cloud.rgb[i][2]);
      }
      buffer += '\n';
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  }
  file.Commit();
}

}  // namespace cloud_internal
}  // namespace epiloc
