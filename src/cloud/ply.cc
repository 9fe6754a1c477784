// PLY 1.0 (ascii, binary little and big endian): the vertex element's positions, intensity and
// colour; every other property and element is skipped.
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

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyProperty {
  std::string name;
  ScalarType type = ScalarType::kNone;        // the value type (item type of a list)
  ScalarType count_type = ScalarType::kNone;  // the count type of a list, kNone for a scalar
  bool is_list() const { return count_type != ScalarType::kNone; }
};

struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> properties;

  bool FixedSize() const {
    for (const PlyProperty& p : properties) {
      if (p.is_list()) return false;
    }
    return true;
  }
  // Bytes of the scalar properties of one record (all of it when FixedSize()).
  size_t ScalarBytes() const {
    size_t bytes = 0;
    for (const PlyProperty& p : properties) {
      if (!p.is_list()) bytes += ScalarSize(p.type);
    }
    return bytes;
  }
};

struct PlyFileHeader {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<PlyElement> elements;
  int64_t num_lines = 0;  // lines of the header, "ply" to "end_header"
};

ScalarType PlyType(const std::string& name) {
  if (name == "char" || name == "int8") return ScalarType::kInt8;
  if (name == "uchar" || name == "uint8") return ScalarType::kUint8;
  if (name == "short" || name == "int16") return ScalarType::kInt16;
  if (name == "ushort" || name == "uint16") return ScalarType::kUint16;
  if (name == "int" || name == "int32") return ScalarType::kInt32;
  if (name == "uint" || name == "uint32") return ScalarType::kUint32;
  if (name == "float" || name == "float32") return ScalarType::kFloat32;
  if (name == "double" || name == "float64") return ScalarType::kFloat64;
  return ScalarType::kNone;
}

PlyFileHeader ParsePlyHeader(const std::string& path, std::ifstream* in) {
  char magic[4] = {};
  in->read(magic, 4);
  if (in->gcount() < 4 || std::memcmp(magic, "ply", 3) != 0 ||
      (magic[3] != '\n' && magic[3] != '\r')) {
    Throw("{}: not a PLY file (it does not start with the line 'ply')", path);
  }
  in->clear();
  in->seekg(0);
  LineReader reader(in, 1, path);
  reader.Next();
  PlyFileHeader header;
  bool have_format = false;
  std::vector<std::string_view> tokens;
  while (reader.Next()) {
    const std::string where = Where(path, reader.line_number());
    SplitTokens(reader.line(), false, &tokens);
    if (tokens.empty()) continue;
    const std::string key(tokens[0]);
    if (key == "end_header") {
      if (!have_format) Throw("{}: the PLY header has no format line", where);
      header.num_lines = reader.line_number();
      return header;
    }
    if (key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      EPILOC_CHECK(tokens.size() == 3, "{}: expected 'format <encoding> 1.0'", where);
      if (tokens[1] == "ascii") {
        header.encoding = PlyEncoding::kAscii;
      } else if (tokens[1] == "binary_little_endian") {
        header.encoding = PlyEncoding::kBinaryLittleEndian;
      } else if (tokens[1] == "binary_big_endian") {
        header.encoding = PlyEncoding::kBinaryBigEndian;
      } else {
        Throw("{}: unknown PLY format '{}'", where, tokens[1]);
      }
      EPILOC_CHECK(tokens[2] == "1.0" || tokens[2] == "1", "{}: unsupported PLY version '{}'",
                   where, tokens[2]);
      have_format = true;
    } else if (key == "element") {
      EPILOC_CHECK(tokens.size() == 3, "{}: expected 'element <name> <count>'", where);
      double count = 0;
      EPILOC_CHECK(ParseNumber(tokens[2], &count) && count >= 0 && count == std::floor(count) &&
                       count < 9e15,
                   "{}: bad element count '{}'", where, tokens[2]);
      PlyElement element;
      element.name = std::string(tokens[1]);
      element.count = static_cast<int64_t>(count);
      header.elements.push_back(std::move(element));
    } else if (key == "property") {
      EPILOC_CHECK(!header.elements.empty(), "{}: property before any element", where);
      PlyProperty property;
      if (tokens.size() == 5 && tokens[1] == "list") {
        property.count_type = PlyType(std::string(tokens[2]));
        property.type = PlyType(std::string(tokens[3]));
        EPILOC_CHECK(property.count_type != ScalarType::kNone && !IsFloat(property.count_type),
                     "{}: bad list count type '{}'", where, tokens[2]);
        EPILOC_CHECK(property.type != ScalarType::kNone, "{}: unknown PLY type '{}'", where,
                     tokens[3]);
        property.name = std::string(tokens[4]);
      } else {
        EPILOC_CHECK(tokens.size() == 3, "{}: expected 'property <type> <name>'", where);
        property.type = PlyType(std::string(tokens[1]));
        EPILOC_CHECK(property.type != ScalarType::kNone, "{}: unknown PLY type '{}'", where,
                     tokens[1]);
        property.name = std::string(tokens[2]);
      }
      header.elements.back().properties.push_back(property);
    } else {
      Throw("{}: unexpected PLY header line '{}'", where, reader.line());
    }
  }
  Throw("{}: the PLY header has no end_header line", path);
}

class PlySource : public PointSource {
 public:
  PlySource(const std::string& path, const CloudReadOptions& options)
      : PointSource(path, options), reader_(&in_, 1, path) {
    OpenForReading(path, &in_);
    header_ = ParsePlyHeader(path, &in_);
    size_t vertex = header_.elements.size();
    for (size_t e = 0; e < header_.elements.size(); ++e) {
      if (header_.elements[e].name == "vertex") {
        vertex = e;
        break;
      }
    }
    if (vertex == header_.elements.size()) {
      Throw("{}: not a point cloud: the PLY has no vertex element", path);
    }
    vertex_ = header_.elements[vertex];
    info_.format = CloudFormat::kPly;
    info_.encoding = header_.encoding == PlyEncoding::kAscii                ? "ascii"
                     : header_.encoding == PlyEncoding::kBinaryLittleEndian ? "binary_little_endian"
                                                                            : "binary_big_endian";
    info_.num_points = vertex_.count;
    BuildLayout();
    reader_ = LineReader(&in_, header_.num_lines + 1, path);
    for (size_t e = 0; e < vertex; ++e) SkipElement(header_.elements[e]);
    if (header_.encoding == PlyEncoding::kAscii) {
      SetTextReserveHint(vertex_.count);
    } else if (vertex_.FixedSize()) {
      CheckBinaryBody(vertex_.count, static_cast<uint64_t>(in_.tellg()), scalar_bytes_);
    } else {
      reserve_hint_ = 0;  // records of varying size: grow as they come
    }
  }

  int64_t Read(int64_t max_records, PointCloud* out) override {
    const int64_t n = std::min(max_records, vertex_.count - done_);
    if (n <= 0) return 0;
    if (header_.encoding == PlyEncoding::kAscii) {
      for (int64_t i = 0; i < n; ++i) ReadAsciiRecord(out);
    } else {
      constexpr int64_t kBlock = 1 << 16;
      for (int64_t begin = 0; begin < n; begin += kBlock) {
        const int64_t count = std::min(kBlock, n - begin);
        ReadBinaryRecords(count);
        DecodeRecords(buffer_.data(), 0, count, layout_, out);
        done_ += count;
      }
    }
    return n;
  }

 private:
  void BuildLayout() {
    const bool swap = (header_.encoding == PlyEncoding::kBinaryBigEndian) == HostIsLittleEndian();
    layout_.swap = swap;
    size_t offset = 0;  // within the record's scalar properties
    for (size_t j = 0; j < vertex_.properties.size(); ++j) {
      const PlyProperty& p = vertex_.properties[j];
      info_.fields.push_back(p.name);
      const FieldRole role = RoleOfFieldName(p.name);
      if (p.is_list()) {
        EPILOC_CHECK(role == FieldRole::kOther, "{}: the PLY vertex property '{}' is a list", path_,
                     p.name);
        continue;
      }
      FieldSlot slot{p.type, offset};
      auto assign = [&](FieldSlot* target) {
        if (!target->valid()) {
          *target = slot;
          role_property_[static_cast<size_t>(role)] = j;
        }
      };
      switch (role) {
        case FieldRole::kX:
          assign(&layout_.x);
          break;
        case FieldRole::kY:
          assign(&layout_.y);
          break;
        case FieldRole::kZ:
          assign(&layout_.z);
          break;
        case FieldRole::kIntensity:
          assign(&layout_.intensity);
          break;
        case FieldRole::kRed:
          assign(&layout_.red);
          break;
        case FieldRole::kGreen:
          assign(&layout_.green);
          break;
        case FieldRole::kBlue:
          assign(&layout_.blue);
          break;
        case FieldRole::kPackedRgb:
          if (ScalarSize(p.type) == 4) assign(&layout_.packed_rgb);
          break;
        case FieldRole::kOther:
          break;
      }
      offset += ScalarSize(p.type);
    }
    for (const auto& [slot, name] :
         {std::pair{&layout_.x, "x"}, {&layout_.y, "y"}, {&layout_.z, "z"}}) {
      EPILOC_CHECK(slot->valid(), "{}: not a point cloud: the PLY vertex element has no '{}'",
                   path_, name);
    }
    info_.has_intensity = layout_.intensity.valid();
    const bool channels = layout_.red.valid() && layout_.green.valid() && layout_.blue.valid();
    if (channels) layout_.packed_rgb = FieldSlot();
    info_.has_colour = channels || layout_.packed_rgb.valid();
    if (!channels) layout_.red = layout_.green = layout_.blue = FieldSlot();
    scalar_bytes_ = vertex_.ScalarBytes();
    layout_.SetStride(scalar_bytes_);
  }

  bool swap() const { return layout_.swap; }

  // Reads `count` vertex records into buffer_ as packed scalar properties.
  void ReadBinaryRecords(int64_t count) {
    if (vertex_.FixedSize()) {
      ReadBody(&in_, static_cast<size_t>(count) * scalar_bytes_, scalar_bytes_, done_,
               vertex_.count, &buffer_);
      return;
    }
    buffer_.resize(static_cast<size_t>(count) * scalar_bytes_);
    for (int64_t r = 0; r < count; ++r) {
      char* record = buffer_.data() + r * scalar_bytes_;
      for (const PlyProperty& p : vertex_.properties) {
        if (p.is_list()) {
          SkipList(p, done_ + r);
        } else {
          ReadExactly(record, ScalarSize(p.type), done_ + r);
          record += ScalarSize(p.type);
        }
      }
    }
  }

  uint64_t FileBytes() {
    if (file_bytes_ == 0) file_bytes_ = std::filesystem::file_size(path_);
    return file_bytes_;
  }

  void ReadExactly(char* data, size_t bytes, int64_t record) {
    in_.read(data, static_cast<std::streamsize>(bytes));
    if (static_cast<size_t>(in_.gcount()) != bytes) {
      Throw("{}: truncated: the header declares {} points, the file ends after {} complete ones",
            path_, vertex_.count, record);
    }
  }

  void SkipList(const PlyProperty& p, int64_t record) {
    char bytes[8];
    ReadExactly(bytes, ScalarSize(p.count_type), record);
    const double count = LoadScalar(bytes, p.count_type, swap());
    EPILOC_CHECK(count >= 0, "{}: negative list length in record {}", path_, record);
    // Seek rather than read: a corrupt length must not allocate (up to 32 GB for a uint32).
    const double skip = count * static_cast<double>(ScalarSize(p.type));
    const std::streamoff at = in_.tellg();
    if (at < 0 || skip > static_cast<double>(FileBytes() - static_cast<uint64_t>(at))) {
      Throw("{}: truncated: a list of {} values in record {} runs past the end of the file", path_,
            count, record);
    }
    in_.seekg(static_cast<std::streamoff>(skip), std::ios::cur);
  }

  void SkipElement(const PlyElement& element) {
    if (header_.encoding == PlyEncoding::kAscii) {
      for (int64_t r = 0; r < element.count; ++r) {
        if (!NextDataLine()) {
          Throw("{}: truncated: the file ends inside the PLY element '{}'", path_, element.name);
        }
      }
    } else if (element.FixedSize()) {
      const double bytes = static_cast<double>(element.count) * element.ScalarBytes();
      const std::streamoff at = in_.tellg();
      if (at < 0 || bytes > static_cast<double>(FileBytes() - static_cast<uint64_t>(at))) {
        Throw("{}: truncated: the file ends inside the PLY element '{}'", path_, element.name);
      }
      in_.seekg(static_cast<std::streamoff>(bytes), std::ios::cur);
    } else {
      std::vector<char> value(8);
      for (int64_t r = 0; r < element.count; ++r) {
        for (const PlyProperty& p : element.properties) {
          if (p.is_list()) {
            SkipList(p, 0);
          } else {
            ReadExactly(value.data(), ScalarSize(p.type), 0);
          }
        }
      }
    }
  }

  bool NextDataLine() {
    while (reader_.Next()) {
      if (reader_.line().find_first_not_of(" \t") != std::string::npos) return true;
    }
    return false;
  }

  void ReadAsciiRecord(PointCloud* out) {
    if (!NextDataLine()) {
      Throw("{}: truncated: the header declares {} points, the file ends after {}", path_,
            vertex_.count, done_);
    }
    auto where = [&] { return Where(path_, reader_.line_number()); };
    SplitTokens(reader_.line(), false, &tokens_);
    values_.assign(vertex_.properties.size(), 0.0);
    size_t t = 0;
    auto next_token = [&]() {
      if (t >= tokens_.size()) {
        Throw("{}: too few values for the vertex's {} properties", where(),
              vertex_.properties.size());
      }
      return tokens_[t++];
    };
    for (size_t j = 0; j < vertex_.properties.size(); ++j) {
      const PlyProperty& p = vertex_.properties[j];
      if (p.is_list()) {
        const double count = ParseNumberOrThrow(next_token(), path_, reader_.line_number());
        EPILOC_CHECK(count >= 0 && count == std::floor(count), "{}: bad list length {}", where(),
                     count);
        for (int64_t k = 0; k < static_cast<int64_t>(count); ++k) next_token();
      } else {
        values_[j] = ParseNumberOrThrow(next_token(), path_, reader_.line_number());
      }
    }
    EPILOC_CHECK(t == tokens_.size(), "{}: {} values where the vertex has {} properties", where(),
                 tokens_.size(), vertex_.properties.size());
    auto value = [&](FieldRole role) { return values_[role_property_[static_cast<size_t>(role)]]; };
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
  PlyFileHeader header_;
  PlyElement vertex_;
  RecordLayout layout_;
  size_t scalar_bytes_ = 0;
  std::array<size_t, 9> role_property_{};  // FieldRole -> index of its vertex property
  LineReader reader_;
  int64_t done_ = 0;
  std::vector<char> buffer_;
  uint64_t file_bytes_ = 0;  // size of the file, read when first needed
  std::vector<std::string_view> tokens_;
  std::vector<double> values_;
};

}  // namespace

std::unique_ptr<PointSource> OpenPlySource(const std::string& path,
                                           const CloudReadOptions& options) {
  return std::make_unique<PlySource>(path, options);
}

size_t PlyRecordBytes(bool with_intensity, bool with_colour) {
  return 3 * sizeof(float) + (with_intensity ? sizeof(float) : 0) + (with_colour ? 3 : 0);
}

std::string PlyHeader(
    int64_t num_points, bool with_intensity, bool with_colour, bool binary, size_t length) {
  std::string header = fmt::format(
      "ply\nformat {} 1.0\ncomment written by epiloc\nelement vertex {}\n"
      "property float x\nproperty float y\nproperty float z\n",
      binary ? "binary_little_endian" : "ascii", num_points);
  if (with_intensity) header += "property float intensity\n";
  if (with_colour) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header += "end_header\n";
  if (length > 0) {
    EPILOC_CHECK(length >= header.size(), "PlyHeader: {} bytes are too few for {} points", length,
                 num_points);
    header.insert(header.find(" epiloc\n") + 7, length - header.size(), ' ');
  }
  return header;
}

char* EncodePlyRecord(const PointCloud& cloud, size_t i, char* out) {
  const bool swap = !HostIsLittleEndian();
  auto put = [&](float value) {
    std::memcpy(out, &value, 4);
    if (swap) std::reverse(out, out + 4);
    out += 4;
  };
  put(cloud.positions[i].x());
  put(cloud.positions[i].y());
  put(cloud.positions[i].z());
  if (cloud.HasIntensity()) put(cloud.intensity[i]);
  if (cloud.HasColour()) {
    std::memcpy(out, cloud.rgb[i].data(), 3);
    out += 3;
  }
  return out;
}

void AppendPlyRecords(const PointCloud& cloud, size_t begin, size_t end, std::string* out) {
  const size_t record_bytes = PlyRecordBytes(cloud.HasIntensity(), cloud.HasColour());
  const size_t old_size = out->size();
  out->resize(old_size + (end - begin) * record_bytes);
  char* p = out->data() + old_size;
  for (size_t i = begin; i < end; ++i) p = EncodePlyRecord(cloud, i, p);
}

void WritePly(const std::string& path, const PointCloud& cloud, bool binary) {
  cloud.Check();
  AtomicOfstream file(path, std::ios::binary | std::ios::trunc);
  std::ofstream& out = file.stream();
  out << PlyHeader(static_cast<int64_t>(cloud.size()), cloud.HasIntensity(), cloud.HasColour(),
                   binary);
  constexpr size_t kBlock = 1 << 16;
  std::string buffer;
  for (size_t begin = 0; begin < cloud.size(); begin += kBlock) {
    const size_t end = std::min(cloud.size(), begin + kBlock);
    buffer.clear();
    if (binary) {
      AppendPlyRecords(cloud, begin, end, &buffer);
    } else {
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
    }
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
  }
  file.Commit();
}

}  // namespace cloud_internal
}  // namespace epiloc
