// PCD (the Point Cloud Library's format), versions 0.5-0.7: DATA ascii, binary and
// binary_compressed (LZF, read only).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iterator>

#include <fmt/format.h>

#include "cloud_io_internal.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"

namespace epiloc {
namespace cloud_internal {
namespace {

enum class PcdData { kAscii, kBinary, kBinaryCompressed };

struct PcdField {
  std::string name;
  char type = 'F';  // F, I or U
  size_t size = 4;
  int64_t count = 1;
  ScalarType scalar = ScalarType::kNone;
};

ScalarType PcdScalarType(char type, size_t size) {
  if (type == 'F' && size == 4) return ScalarType::kFloat32;
  if (type == 'F' && size == 8) return ScalarType::kFloat64;
  if (type == 'I' && size == 1) return ScalarType::kInt8;
  if (type == 'I' && size == 2) return ScalarType::kInt16;
  if (type == 'I' && size == 4) return ScalarType::kInt32;
  if (type == 'I' && size == 8) return ScalarType::kInt64;
  if (type == 'U' && size == 1) return ScalarType::kUint8;
  if (type == 'U' && size == 2) return ScalarType::kUint16;
  if (type == 'U' && size == 4) return ScalarType::kUint32;
  if (type == 'U' && size == 8) return ScalarType::kUint64;
  return ScalarType::kNone;
}

int64_t ParseCount(std::string_view token, const std::string& where) {
  double value = 0;
  EPILOC_CHECK(
      ParseNumber(token, &value) && value >= 0 && value == std::floor(value) && value < 9e15,
      "{}: '{}' is not a non-negative integer", where, token);
  return static_cast<int64_t>(value);
}

// Decompresses liblzf's format (PCL's binary_compressed): a control byte c < 32 starts a literal
// run of c + 1 bytes; otherwise it is a back reference of (c >> 5) + 2 bytes (7 means: add the
// next byte) to the distance ((c & 31) << 8) + the next byte + 1. False for corrupt data.
bool LzfDecompress(const uint8_t* in, size_t in_size, uint8_t* out, size_t out_size) {
  size_t ip = 0;
  size_t op = 0;
  while (ip < in_size) {
    const size_t control = in[ip++];
    if (control < 32) {
      const size_t length = control + 1;
      if (ip + length > in_size || op + length > out_size) return false;
      std::memcpy(out + op, in + ip, length);
      ip += length;
      op += length;
      continue;
    }
    size_t length = control >> 5;
    if (length == 7) {
      if (ip >= in_size) return false;
      length += in[ip++];
    }
    if (ip >= in_size) return false;
    const size_t distance = ((control & 0x1f) << 8) + in[ip++] + 1;
    length += 2;
    if (distance > op || op + length > out_size) return false;
    for (size_t k = 0; k < length; ++k, ++op) out[op] = out[op - distance];  // may overlap
  }
  return op == out_size;
}

class PcdSource : public PointSource {
 public:
  PcdSource(const std::string& path, const CloudReadOptions& options)
      : PointSource(path, options), reader_(&in_, 1, path) {
    OpenForReading(path, &in_);
    const int first = in_.peek();
    if (first != '#' && first != 'V' && first != 'F') {
      Throw("{}: not a PCD file (it does not start with a comment, VERSION or FIELDS)", path);
    }
    ParseHeader();
    BuildLayout();
    if (data_ == PcdData::kAscii) {
      SetTextReserveHint(num_points_);
    } else if (data_ == PcdData::kBinary) {
      CheckBinaryBody(num_points_, static_cast<uint64_t>(in_.tellg()), record_bytes_);
    } else {
      Decompress();
      reserve_hint_ = num_points_;
    }
  }

  int64_t Read(int64_t max_records, PointCloud* out) override {
    const int64_t n = std::min(max_records, num_points_ - done_);
    if (n <= 0) return 0;
    if (data_ == PcdData::kAscii) {
      for (int64_t i = 0; i < n; ++i) ReadAsciiRecord(out);
    } else if (data_ == PcdData::kBinary) {
      constexpr int64_t kBlock = 1 << 16;
      for (int64_t begin = 0; begin < n; begin += kBlock) {
        const int64_t count = std::min(kBlock, n - begin);
        ReadBody(&in_, static_cast<size_t>(count) * record_bytes_, record_bytes_, done_,
                 num_points_, &buffer_);
        DecodeRecords(buffer_.data(), 0, count, layout_, out);
        done_ += count;
      }
    } else {
      DecodeRecords(buffer_.data(), done_, n, layout_, out);
      done_ += n;
      if (done_ == num_points_) std::vector<char>().swap(buffer_);
    }
    return n;
  }

 private:
  void ParseHeader() {
    std::vector<std::string_view> tokens;
    int64_t width = -1;
    int64_t height = 1;
    num_points_ = -1;
    bool have_data = false;
    while (!have_data && reader_.Next()) {
      auto where = [&] { return Where(path_, reader_.line_number()); };
      SplitTokens(reader_.line(), false, &tokens);
      if (tokens.empty() || tokens[0].front() == '#') continue;
      const std::string key(tokens[0]);
      const size_t n = tokens.size() - 1;
      if (key == "VERSION" || key == "VIEWPOINT") continue;
      if (key == "FIELDS") {
        fields_.clear();
        for (size_t k = 1; k < tokens.size(); ++k) {
          fields_.push_back(PcdField{std::string(tokens[k])});
        }
      } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
        // SIZE is 1, 2, 4 or 8 (checked with TYPE later); COUNT bounds the record size.
        EPILOC_CHECK(!fields_.empty(), "{}: {} before FIELDS", where(), key);
        EPILOC_CHECK(n == fields_.size(), "{}: {} has {} entries for {} fields", where(), key, n,
                     fields_.size());
        for (size_t k = 0; k < n; ++k) {
          if (key == "SIZE") {
            fields_[k].size = static_cast<size_t>(ParseCount(tokens[k + 1], where()));
          } else if (key == "COUNT") {
            fields_[k].count = ParseCount(tokens[k + 1], where());
            EPILOC_CHECK(fields_[k].count <= (1 << 20), "{}: COUNT {} is too large", where(),
                         fields_[k].count);
          } else {
            EPILOC_CHECK(tokens[k + 1] == "F" || tokens[k + 1] == "I" || tokens[k + 1] == "U",
                         "{}: unknown TYPE '{}'", where(), tokens[k + 1]);
            fields_[k].type = tokens[k + 1][0];
          }
        }
      } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
        EPILOC_CHECK(n == 1, "{}: {} takes one value", where(), key);
        const int64_t value = ParseCount(tokens[1], where());
        (key == "WIDTH" ? width : key == "HEIGHT" ? height : num_points_) = value;
      } else if (key == "DATA") {
        EPILOC_CHECK(n == 1, "{}: DATA takes one value", where());
        if (tokens[1] == "ascii") {
          data_ = PcdData::kAscii;
        } else if (tokens[1] == "binary") {
          data_ = PcdData::kBinary;
        } else if (tokens[1] == "binary_compressed") {
          data_ = PcdData::kBinaryCompressed;
        } else {
          Throw("{}: unknown PCD DATA '{}'", where(), tokens[1]);
        }
        have_data = true;
      } else if (reader_.line_number() == 1) {
        Throw("{}: not a PCD file (first line '{}')", path_, reader_.line());
      } else {
        Throw("{}: unexpected PCD header line '{}'", where(), reader_.line());
      }
    }
    EPILOC_CHECK(have_data, "{}: the PCD header has no DATA line", path_);
    EPILOC_CHECK(!fields_.empty(), "{}: the PCD header has no FIELDS line", path_);
    EPILOC_CHECK(width >= 0 || num_points_ >= 0, "{}: the PCD header has neither WIDTH nor POINTS",
                 path_);
    for (const int64_t count : {width, height, num_points_}) {
      EPILOC_CHECK(count <= kMaxPointsPerFile, "{}: corrupt header: {} points", path_, count);
    }
    // Both at most 2^33 now: the product fits in 64 bits.
    if (width >= 0 && height > 0 && width > kMaxPointsPerFile / height) {
      Throw("{}: corrupt header: WIDTH x HEIGHT = {} x {} points", path_, width, height);
    }
    if (num_points_ < 0) num_points_ = width * height;
    if (width >= 0 && width * height != num_points_) {
      Throw("{}: POINTS {} is not WIDTH x HEIGHT = {} x {}", path_, num_points_, width, height);
    }
    info_.format = CloudFormat::kPcd;
    info_.encoding = data_ == PcdData::kAscii    ? "ascii"
                     : data_ == PcdData::kBinary ? "binary"
                                                 : "binary_compressed";
    info_.num_points = num_points_;
  }

  void BuildLayout() {
    size_t offset = 0;
    size_t token = 0;
    for (PcdField& field : fields_) {
      field.scalar = PcdScalarType(field.type, field.size);
      EPILOC_CHECK(field.scalar != ScalarType::kNone, "{}: PCD field '{}' has TYPE {} SIZE {}",
                   path_, field.name, field.type, field.size);
      info_.fields.push_back(field.name);
      const FieldRole role = RoleOfFieldName(field.name);
      const bool positional =
          role == FieldRole::kX || role == FieldRole::kY || role == FieldRole::kZ;
      EPILOC_CHECK(field.count == 1 || !positional, "{}: PCD field '{}' has COUNT {}", path_,
                   field.name, field.count);
      FieldSlot* target = nullptr;
      if (field.count == 1) {
        switch (role) {
          case FieldRole::kX:
            target = &layout_.x;
            break;
          case FieldRole::kY:
            target = &layout_.y;
            break;
          case FieldRole::kZ:
            target = &layout_.z;
            break;
          case FieldRole::kIntensity:
            target = &layout_.intensity;
            break;
          case FieldRole::kRed:
            target = &layout_.red;
            break;
          case FieldRole::kGreen:
            target = &layout_.green;
            break;
          case FieldRole::kBlue:
            target = &layout_.blue;
            break;
          case FieldRole::kPackedRgb:
            if (field.size == 4) target = &layout_.packed_rgb;
            break;
          case FieldRole::kOther:
            break;
        }
      }
      if (target != nullptr && !target->valid()) {
        *target = FieldSlot{field.scalar, offset};
        role_token_[static_cast<size_t>(role)] = token;
      }
      // binary_compressed stores field by field: the field's values for all points in a row.
      offset += field.size * static_cast<size_t>(field.count) *
                (data_ == PcdData::kBinaryCompressed ? static_cast<size_t>(num_points_) : 1);
      record_bytes_ += field.size * static_cast<size_t>(field.count);
      token += static_cast<size_t>(field.count);
    }
    num_tokens_ = token;
    for (const auto& [slot, name] :
         {std::pair{&layout_.x, "x"}, {&layout_.y, "y"}, {&layout_.z, "z"}}) {
      EPILOC_CHECK(slot->valid(), "{}: not a point cloud: the PCD has no field '{}'", path_, name);
    }
    const bool channels = layout_.red.valid() && layout_.green.valid() && layout_.blue.valid();
    if (channels) layout_.packed_rgb = FieldSlot();
    if (!channels) layout_.red = layout_.green = layout_.blue = FieldSlot();
    info_.has_intensity = layout_.intensity.valid();
    info_.has_colour = channels || layout_.packed_rgb.valid();
    layout_.swap = !HostIsLittleEndian();  // PCL writes the host's order: little endian
    if (data_ == PcdData::kBinaryCompressed) {
      for (FieldSlot* slot : {&layout_.x, &layout_.y, &layout_.z, &layout_.intensity, &layout_.red,
                              &layout_.green, &layout_.blue, &layout_.packed_rgb}) {
        if (slot->valid()) slot->stride = ScalarSize(slot->type);
      }
    } else {
      layout_.SetStride(record_bytes_);
    }
  }

  void Decompress() {
    char sizes[8];
    in_.read(sizes, 8);
    EPILOC_CHECK(in_.gcount() == 8, "{}: truncated: the compressed PCD body has no size header",
                 path_);
    const auto compressed =
        static_cast<uint32_t>(LoadScalar(sizes, ScalarType::kUint32, !HostIsLittleEndian()));
    const auto uncompressed =
        static_cast<uint32_t>(LoadScalar(sizes + 4, ScalarType::kUint32, !HostIsLittleEndian()));
    EPILOC_CHECK(num_points_ == 0 || record_bytes_ <= (uint64_t{1} << 32) / num_points_,
                 "{}: corrupt header: {} points of {} bytes", path_, num_points_, record_bytes_);
    const size_t expected = record_bytes_ * static_cast<size_t>(num_points_);
    // The header's sizes are checked against the file before anything is allocated: a 1 kB file
    // must not make us reserve gigabytes.
    const uint64_t body = static_cast<uint64_t>(in_.tellg());
    const uint64_t file_bytes = std::filesystem::file_size(path_);
    EPILOC_CHECK(compressed <= (file_bytes > body ? file_bytes - body : 0),
                 "{}: truncated: the compressed PCD body claims {} bytes, the file has {} after "
                 "the header",
                 path_, compressed, file_bytes > body ? file_bytes - body : 0);
    EPILOC_CHECK(uncompressed == expected,
                 "{}: the compressed PCD body holds {} bytes, {} points of {} bytes need {}", path_,
                 uncompressed, num_points_, record_bytes_, expected);
    // LZF expands at most ~90-fold (a 264-byte back reference costs 3 bytes).
    EPILOC_CHECK(uncompressed <= 90.0 * compressed + 64,
                 "{}: corrupt compressed PCD body ({} bytes claim to hold {})", path_, compressed,
                 uncompressed);
    std::vector<char> packed(compressed);
    in_.read(packed.data(), compressed);
    EPILOC_CHECK(static_cast<uint32_t>(in_.gcount()) == compressed,
                 "{}: truncated: the compressed PCD body has {} of {} bytes", path_, in_.gcount(),
                 compressed);
    buffer_.resize(expected);
    if (!LzfDecompress(reinterpret_cast<const uint8_t*>(packed.data()), packed.size(),
                       reinterpret_cast<uint8_t*>(buffer_.data()), buffer_.size())) {
      Throw("{}: corrupt LZF data in the compressed PCD body", path_);
    }
  }

  void ReadAsciiRecord(PointCloud* out) {
    do {
      if (!reader_.Next()) {
        Throw("{}: truncated: the header declares {} points, the file ends after {}", path_,
              num_points_, done_);
      }
    } while (reader_.line().find_first_not_of(" \t") == std::string::npos);
    const std::string where = Where(path_, reader_.line_number());
    SplitTokens(reader_.line(), false, &tokens_);
    EPILOC_CHECK(tokens_.size() == num_tokens_, "{}: {} values where the fields need {}", where,
                 tokens_.size(), num_tokens_);
    auto value = [&](FieldRole role) {
      return ParseNumberOrThrow(tokens_[role_token_[static_cast<size_t>(role)]], where);
    };
    float intensity = 0.0f;
    if (with_intensity()) {
      intensity = ConvertIntensity(value(FieldRole::kIntensity), layout_.intensity.type,
                                   options_.float_intensity_scale, &stats_);
    }
    std::array<uint8_t, 3> rgb{};
    if (with_colour()) {
      if (layout_.packed_rgb.valid()) {
        rgb = UnpackRgb(PackedBits(value(FieldRole::kPackedRgb), layout_.packed_rgb.type));
      } else {
        rgb = {ConvertColour(value(FieldRole::kRed), layout_.red.type),
               ConvertColour(value(FieldRole::kGreen), layout_.green.type),
               ConvertColour(value(FieldRole::kBlue), layout_.blue.type)};
      }
    }
    AddPoint(out, value(FieldRole::kX), value(FieldRole::kY), value(FieldRole::kZ), intensity, rgb);
    ++done_;
  }

  std::ifstream in_;
  LineReader reader_;
  std::vector<PcdField> fields_;
  PcdData data_ = PcdData::kAscii;
  int64_t num_points_ = 0;
  size_t record_bytes_ = 0;
  size_t num_tokens_ = 0;
  RecordLayout layout_;
  std::array<size_t, 9> role_token_{};  // FieldRole -> index of its value in an ascii line
  int64_t done_ = 0;
  std::vector<char> buffer_;
  std::vector<std::string_view> tokens_;
};

}  // namespace

std::unique_ptr<PointSource> OpenPcdSource(const std::string& path,
                                           const CloudReadOptions& options) {
  return std::make_unique<PcdSource>(path, options);
}

void WritePcd(const std::string& path, const PointCloud& cloud, bool binary) {
  cloud.Check();
  const bool intensity = cloud.HasIntensity();
  const bool colour = cloud.HasColour();
  AtomicOfstream file(path, std::ios::binary | std::ios::trunc);
  std::ofstream& out = file.stream();
  const size_t n = cloud.size();
  out << "# .PCD v0.7 - Point Cloud Data file format (written by epiloc)\nVERSION 0.7\n"
      << "FIELDS x y z" << (intensity ? " intensity" : "") << (colour ? " rgb" : "") << "\n"
      << "SIZE 4 4 4" << (intensity ? " 4" : "") << (colour ? " 4" : "") << "\n"
      << "TYPE F F F" << (intensity ? " F" : "") << (colour ? " U" : "") << "\n"
      << "COUNT 1 1 1" << (intensity ? " 1" : "") << (colour ? " 1" : "") << "\n"
      << "WIDTH " << n << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n << "\n"
      << "DATA " << (binary ? "binary" : "ascii") << "\n";
  constexpr size_t kBlock = 1 << 16;
  std::string buffer;
  auto packed = [&](size_t i) {
    return (uint32_t{cloud.rgb[i][0]} << 16) | (uint32_t{cloud.rgb[i][1]} << 8) | cloud.rgb[i][2];
  };
  for (size_t begin = 0; begin < n; begin += kBlock) {
    const size_t end = std::min(n, begin + kBlock);
    buffer.clear();
    auto it = std::back_inserter(buffer);
    for (size_t i = begin; i < end; ++i) {
      const Eigen::Vector3f& p = cloud.positions[i];
      if (binary) {
        AppendFloatLE(p.x(), &buffer);
        AppendFloatLE(p.y(), &buffer);
        AppendFloatLE(p.z(), &buffer);
        if (intensity) AppendFloatLE(cloud.intensity[i], &buffer);
        if (colour) {
          const uint32_t value = packed(i);
          char bytes[4];
          std::memcpy(bytes, &value, 4);
          if (!HostIsLittleEndian()) std::reverse(bytes, bytes + 4);
          buffer.append(bytes, 4);
        }
      } else {
        fmt::format_to(it, "{} {} {}", p.x(), p.y(), p.z());
        if (intensity) fmt::format_to(it, " {}", cloud.intensity[i]);
        if (colour) fmt::format_to(it, " {}", packed(i));
        buffer += '\n';
      }
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  }
  file.Commit();
}

}  // namespace cloud_internal
}  // namespace epiloc
