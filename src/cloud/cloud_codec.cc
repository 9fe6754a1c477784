// Scalar decoding, text tokenising and the point-appending core shared by the format readers.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "cloud_io_internal.h"
#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"

namespace epiloc {
namespace cloud_internal {
namespace {

template <typename T>
inline T LoadAs(const char* data, bool swap) {
  T value;
  if (!swap) {
    std::memcpy(&value, data, sizeof(T));
    return value;
  }
  char bytes[sizeof(T)];
  std::reverse_copy(data, data + sizeof(T), bytes);
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

template <typename T>
void LoadTyped(
    const char* data, const FieldSlot& slot, bool swap, int64_t first, int64_t n, double* out) {
  const char* p = data + slot.offset + first * slot.stride;
  if (slot.scale == 1.0 && slot.shift == 0.0) {
    for (int64_t i = 0; i < n; ++i, p += slot.stride) {
      out[i] = static_cast<double>(LoadAs<T>(p, swap));
    }
  } else {
    for (int64_t i = 0; i < n; ++i, p += slot.stride) {
      out[i] = static_cast<double>(LoadAs<T>(p, swap)) * slot.scale + slot.shift;
    }
  }
}

}  // namespace

void LoadColumn(
    const char* data, const FieldSlot& slot, bool swap, int64_t first, int64_t n, double* out) {
  switch (slot.type) {
    case ScalarType::kInt8:
      return LoadTyped<int8_t>(data, slot, false, first, n, out);
    case ScalarType::kUint8:
      return LoadTyped<uint8_t>(data, slot, false, first, n, out);
    case ScalarType::kInt16:
      return LoadTyped<int16_t>(data, slot, swap, first, n, out);
    case ScalarType::kUint16:
      return LoadTyped<uint16_t>(data, slot, swap, first, n, out);
    case ScalarType::kInt32:
      return LoadTyped<int32_t>(data, slot, swap, first, n, out);
    case ScalarType::kUint32:
      return LoadTyped<uint32_t>(data, slot, swap, first, n, out);
    case ScalarType::kInt64:
      return LoadTyped<int64_t>(data, slot, swap, first, n, out);
    case ScalarType::kUint64:
      return LoadTyped<uint64_t>(data, slot, swap, first, n, out);
    case ScalarType::kFloat32:
      return LoadTyped<float>(data, slot, swap, first, n, out);
    case ScalarType::kFloat64:
      return LoadTyped<double>(data, slot, swap, first, n, out);
    case ScalarType::kNone:
      break;
  }
  std::fill(out, out + n, 0.0);
}

size_t ScalarSize(ScalarType type) {
  switch (type) {
    case ScalarType::kNone:
      return 0;
    case ScalarType::kInt8:
    case ScalarType::kUint8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kInt64:
    case ScalarType::kUint64:
    case ScalarType::kFloat64:
      return 8;
  }
  return 0;
}

bool IsFloat(ScalarType type) {
  return type == ScalarType::kFloat32 || type == ScalarType::kFloat64;
}

bool HostIsLittleEndian() {
  const uint16_t one = 1;
  uint8_t first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

double LoadScalar(const char* data, ScalarType type, bool swap) {
  switch (type) {
    case ScalarType::kInt8:
      return LoadAs<int8_t>(data, false);
    case ScalarType::kUint8:
      return LoadAs<uint8_t>(data, false);
    case ScalarType::kInt16:
      return LoadAs<int16_t>(data, swap);
    case ScalarType::kUint16:
      return LoadAs<uint16_t>(data, swap);
    case ScalarType::kInt32:
      return LoadAs<int32_t>(data, swap);
    case ScalarType::kUint32:
      return LoadAs<uint32_t>(data, swap);
    case ScalarType::kInt64:
      return static_cast<double>(LoadAs<int64_t>(data, swap));
    case ScalarType::kUint64:
      return static_cast<double>(LoadAs<uint64_t>(data, swap));
    case ScalarType::kFloat32:
      return LoadAs<float>(data, swap);
    case ScalarType::kFloat64:
      return LoadAs<double>(data, swap);
    case ScalarType::kNone:
      break;
  }
  return 0.0;
}

float ConvertIntensity(double value, ScalarType type, double float_scale, CloudReadStats* stats) {
  double v = value;
  if (type == ScalarType::kUint8) {
    v /= 255.0;
  } else if (type == ScalarType::kUint16) {
    v /= 65535.0;
  } else {
    v *= float_scale;
  }
  if (!(v >= 0.0 && v <= 1.0)) {
    ++stats->num_intensity_clamped;
    v = v > 1.0 ? 1.0 : 0.0;  // NaN -> 0
  }
  return static_cast<float>(v);
}

uint8_t ConvertColour(double value, ScalarType type) {
  double v = value;
  if (type == ScalarType::kUint16) {
    v /= 257.0;
  } else if (IsFloat(type)) {
    v *= 255.0;
  }
  if (!(v >= 0.0)) return 0;  // NaN too
  if (v >= 255.0) return 255;
  return static_cast<uint8_t>(v + 0.5);
}

std::array<uint8_t, 3> UnpackRgb(uint32_t packed) {
  return {static_cast<uint8_t>((packed >> 16) & 0xff), static_cast<uint8_t>((packed >> 8) & 0xff),
          static_cast<uint8_t>(packed & 0xff)};
}

uint32_t PackedBits(double value, ScalarType type) {
  if (IsFloat(type)) {
    const auto f = static_cast<float>(value);
    uint32_t bits;
    std::memcpy(&bits, &f, 4);
    return bits;
  }
  if (!(value >= 0.0 && value <= 4294967295.0)) return 0;
  return static_cast<uint32_t>(value);
}

void RecordLayout::SetStride(size_t record_bytes) {
  for (FieldSlot* slot : {&x, &y, &z, &intensity, &red, &green, &blue, &packed_rgb}) {
    if (slot->valid()) slot->stride = record_bytes;
  }
}

bool LineReader::Next() {
  if (!ReadLine(*in_, line_, path_, line_number_ + 1)) return false;
  ++line_number_;
  if (!line_.empty() && line_.back() == '\r') line_.pop_back();
  return true;
}

void SplitTokens(std::string_view line, bool commas, std::vector<std::string_view>* tokens) {
  tokens->clear();
  auto is_separator = [commas](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f' ||
           (commas && (c == ',' || c == ';'));
  };
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_separator(line[i])) ++i;
    const size_t begin = i;
    while (i < line.size() && !is_separator(line[i])) ++i;
    if (i > begin) tokens->push_back(line.substr(begin, i - begin));
  }
}

bool ParseNumber(std::string_view token, double* value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const char* end = token.data() + token.size();
  const auto [ptr, error] = std::from_chars(token.data(), end, *value);
  if (error == std::errc::result_out_of_range && ptr == end) {
    // Overflow and underflow: fall back to strtod's inf / denormal / 0.
    *value = std::strtod(std::string(token).c_str(), nullptr);
    return true;
  }
  return error == std::errc() && ptr == end;
}

double ParseNumberOrThrow(std::string_view token, const std::string& where) {
  double value = 0.0;
  if (!ParseNumber(token, &value)) Throw("{}: '{}' is not a number", where, token);
  return value;
}

double ParseNumberOrThrow(std::string_view token, const std::string& path, int64_t line) {
  double value = 0.0;
  if (!ParseNumber(token, &value)) Throw("{}: '{}' is not a number", Where(path, line), token);
  return value;
}

std::string ToLower(std::string_view text) {
  std::string lower(text);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower;
}

FieldRole RoleOfFieldName(const std::string& name) {
  const std::string n = ToLower(name);
  if (n == "x") return FieldRole::kX;
  if (n == "y") return FieldRole::kY;
  if (n == "z") return FieldRole::kZ;
  if (n == "intensity" || n == "scalar_intensity" || n == "reflectance" ||
      n == "scalar_reflectance" || n == "i") {
    return FieldRole::kIntensity;
  }
  if (n == "red" || n == "r" || n == "diffuse_red") return FieldRole::kRed;
  if (n == "green" || n == "g" || n == "diffuse_green") return FieldRole::kGreen;
  if (n == "blue" || n == "b" || n == "diffuse_blue") return FieldRole::kBlue;
  if (n == "rgb" || n == "rgba") return FieldRole::kPackedRgb;
  return FieldRole::kOther;
}

PointSource::PointSource(std::string path, const CloudReadOptions& options)
    : path_(std::move(path)), options_(options) {}

void PointSource::AddPoint(PointCloud* out,
                           double x,
                           double y,
                           double z,
                           float intensity,
                           const std::array<uint8_t, 3>& rgb) {
  ++stats_.num_records;
  const Eigen::Vector3f p(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
  if (!p.allFinite()) {
    ++stats_.num_non_finite;
    return;
  }
  ++stats_.num_points;
  out->positions.push_back(p);
  if (with_intensity()) out->intensity.push_back(intensity);
  if (with_colour()) out->rgb.push_back(rgb);
}

void PointSource::DecodeRecords(
    const char* data, int64_t first, int64_t count, const RecordLayout& layout, PointCloud* out) {
  const bool intensity = with_intensity();
  const bool colour = with_colour();
  out->positions.reserve(out->positions.size() + static_cast<size_t>(count));
  if (intensity) out->intensity.reserve(out->intensity.size() + static_cast<size_t>(count));
  if (colour) out->rgb.reserve(out->rgb.size() + static_cast<size_t>(count));
  // Column by column in batches, so the type dispatch happens once per batch, not per value.
  constexpr int64_t kBatch = 4096;
  columns_.resize(7 * kBatch);
  double* x = columns_.data();
  double* y = x + kBatch;
  double* z = y + kBatch;
  double* values = z + kBatch;
  double* red = values + kBatch;
  double* green = red + kBatch;
  double* blue = green + kBatch;
  const double intensity_scale = layout.intensity.type == ScalarType::kUint8 ? 1.0 / 255.0
                                 : layout.intensity.type == ScalarType::kUint16
                                     ? 1.0 / 65535.0
                                     : options_.float_intensity_scale;
  for (int64_t begin = first; begin < first + count; begin += kBatch) {
    const int64_t n = std::min(kBatch, first + count - begin);
    LoadColumn(data, layout.x, layout.swap, begin, n, x);
    LoadColumn(data, layout.y, layout.swap, begin, n, y);
    LoadColumn(data, layout.z, layout.swap, begin, n, z);
    if (intensity) LoadColumn(data, layout.intensity, layout.swap, begin, n, values);
    if (colour && layout.packed_rgb.valid()) {
      const FieldSlot& slot = layout.packed_rgb;
      for (int64_t i = 0; i < n; ++i) {
        const auto packed =
            LoadAs<uint32_t>(data + slot.offset + (begin + i) * slot.stride, layout.swap);
        red[i] = (packed >> 16) & 0xff;
        green[i] = (packed >> 8) & 0xff;
        blue[i] = packed & 0xff;
      }
    } else if (colour) {
      LoadColumn(data, layout.red, layout.swap, begin, n, red);
      LoadColumn(data, layout.green, layout.swap, begin, n, green);
      LoadColumn(data, layout.blue, layout.swap, begin, n, blue);
    }
    const ScalarType colour_type = layout.packed_rgb.valid() ? ScalarType::kUint8 : layout.red.type;
    // Written in place (sizes grown by n, then cut to the points kept).
    size_t kept = out->positions.size();
    out->positions.resize(kept + static_cast<size_t>(n));
    if (intensity) out->intensity.resize(kept + static_cast<size_t>(n));
    if (colour) out->rgb.resize(kept + static_cast<size_t>(n));
    for (int64_t i = 0; i < n; ++i) {
      const Eigen::Vector3f p(static_cast<float>(x[i]), static_cast<float>(y[i]),
                              static_cast<float>(z[i]));
      if (!p.allFinite()) {
        ++stats_.num_non_finite;
        continue;
      }
      out->positions[kept] = p;
      if (intensity) {
        double v = values[i] * intensity_scale;
        if (!(v >= 0.0 && v <= 1.0)) {
          ++stats_.num_intensity_clamped;
          v = v > 1.0 ? 1.0 : 0.0;
        }
        out->intensity[kept] = static_cast<float>(v);
      }
      if (colour) {
        if (colour_type == ScalarType::kUint8) {
          out->rgb[kept] = {static_cast<uint8_t>(red[i]), static_cast<uint8_t>(green[i]),
                            static_cast<uint8_t>(blue[i])};
        } else {
          out->rgb[kept] = {ConvertColour(red[i], colour_type),
                            ConvertColour(green[i], colour_type),
                            ConvertColour(blue[i], colour_type)};
        }
      }
      ++kept;
    }
    out->positions.resize(kept);
    if (intensity) out->intensity.resize(kept);
    if (colour) out->rgb.resize(kept);
  }
  stats_.num_records += count;
  stats_.num_points = stats_.num_records - stats_.num_non_finite;
}

void PointSource::CheckBinaryBody(int64_t declared, uint64_t body_offset, size_t record_bytes) {
  if (declared < 0) Throw("{}: corrupt header: {} points declared", path_, declared);
  EPILOC_CHECK(record_bytes > 0, "{}: corrupt header: records of 0 bytes", path_);
  const uint64_t size = std::filesystem::file_size(path_);
  const auto room =
      static_cast<int64_t>(size > body_offset ? (size - body_offset) / record_bytes : 0);
  if (declared > room) {
    Throw("{}: truncated: the header declares {} points, the file ends after {} complete ones",
          path_, declared, room);
  }
  if (declared > kMaxPointsPerFile) Throw("{}: corrupt header: {} points declared", path_, declared);
  reserve_hint_ = declared;
}

void PointSource::SetTextReserveHint(int64_t declared) {
  const auto room = static_cast<int64_t>(std::filesystem::file_size(path_) / 6);
  reserve_hint_ = std::max<int64_t>(0, std::min(declared, room));
}

void PointSource::ReadBody(std::ifstream* in,
                           size_t bytes,
                           size_t record_bytes,
                           int64_t records_before,
                           int64_t declared,
                           std::vector<char>* buffer) {
  buffer->resize(bytes);
  in->read(buffer->data(), static_cast<std::streamsize>(bytes));
  const auto got = static_cast<size_t>(in->gcount());
  if (got != bytes) {
    Throw("{}: truncated: the header declares {} points, the file ends after {} complete ones",
          path_, declared, records_before + static_cast<int64_t>(got / record_bytes));
  }
}

void OpenForReading(const std::string& path, std::ifstream* in) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) Throw("{}: is a directory, not a file", path);
  in->open(path, std::ios::binary);
  if (!*in) Throw("{}: cannot open ({})", path, std::strerror(errno));
}

void OpenForWriting(const std::string& path, std::ofstream* out) {
  out->open(path, std::ios::binary | std::ios::trunc);
  if (!*out) Throw("{}: cannot open for writing ({})", path, std::strerror(errno));
}

void CloseOrThrow(const std::string& path, std::ofstream* out) {
  out->close();
  if (!*out) Throw("{}: write failed", path);
}

void AppendFloatLE(float value, std::string* out) {
  char bytes[4];
  std::memcpy(bytes, &value, 4);
  if (!HostIsLittleEndian()) std::reverse(bytes, bytes + 4);
  out->append(bytes, 4);
}

}  // namespace cloud_internal
}  // namespace epiloc
