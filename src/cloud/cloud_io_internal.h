// Private to the cloud module: what the format readers and writers share.
#pragma once

#include <array>
#include <cstdint>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "epiloc/cloud/cloud_io.h"
#include "epiloc/cloud/point_cloud.h"

namespace epiloc {
namespace cloud_internal {

// Scalar types of binary point records (PLY, PCD, LAS, KITTI).
enum class ScalarType {
  kNone,
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kInt64,
  kUint64,
  kFloat32,
  kFloat64
};

// Bytes of one value; 0 for kNone.
size_t ScalarSize(ScalarType type);
bool IsFloat(ScalarType type);
bool HostIsLittleEndian();
// The value at `data` (unaligned; byte order reversed when `swap`) as a double.
double LoadScalar(const char* data, ScalarType type, bool swap);

// A stored intensity in [0, 1] (see cloud_io.h); counts clamping in stats.
float ConvertIntensity(double value, ScalarType type, double float_scale, CloudReadStats* stats);
// A stored colour channel in 0..255 (see cloud_io.h).
uint8_t ConvertColour(double value, ScalarType type);
// PCD's packed colour 0x00RRGGBB -> R G B.
std::array<uint8_t, 3> UnpackRgb(uint32_t packed);
// The 32 bits of a packed colour read from text: the float's bits for a float field, else the
// integer.
uint32_t PackedBits(double value, ScalarType type);

// Where one attribute of point i sits in a binary body: data + offset + i * stride, times scale
// plus shift (LAS stores scaled integers).
struct FieldSlot {
  ScalarType type = ScalarType::kNone;
  size_t offset = 0;
  size_t stride = 0;
  double scale = 1.0;
  double shift = 0.0;
  bool valid() const { return type != ScalarType::kNone; }
};

// Loads n values of `slot` for points first .. first + n - 1 of a binary body as doubles (times
// scale plus shift); zeros for an invalid slot.
void LoadColumn(
    const char* data, const FieldSlot& slot, bool swap, int64_t first, int64_t n, double* out);

// The attributes of binary point records.
struct RecordLayout {
  bool swap = false;  // stored in the byte order opposite to the host's
  FieldSlot x, y, z;
  FieldSlot intensity;
  FieldSlot red, green, blue;
  FieldSlot packed_rgb;  // PCD rgb / rgba (4 bytes, 0x00RRGGBB)
  // Sets stride on every valid slot (records of `record_bytes` bytes, one after another).
  void SetStride(size_t record_bytes);
};

// Reads a text file line by line, counting lines for messages; '\r' before '\n' is removed.
class LineReader {
 public:
  LineReader(std::ifstream* in, int64_t first_line, std::string path)
      : in_(in), line_number_(first_line - 1), path_(std::move(path)) {}
  // Next line into line(); false at the end of the file.
  bool Next();
  const std::string& line() const { return line_; }
  int64_t line_number() const { return line_number_; }

 private:
  std::ifstream* in_;
  std::string line_;
  int64_t line_number_;
  std::string path_;  // for messages
};

// Splits at white space (and at ',' and ';' when `commas`) into `tokens` (views into `line`).
void SplitTokens(std::string_view line, bool commas, std::vector<std::string_view>* tokens);
// Parses a whole token as a number ("nan" and "inf" allowed; a leading '+' too); false otherwise.
bool ParseNumber(std::string_view token, double* value);
// As ParseNumber, throwing Error "<where>: '<token>' is not a number".
double ParseNumberOrThrow(std::string_view token, const std::string& where);
// As ParseNumber, throwing Error "<path>:<line>: '<token>' is not a number" (the message is
// only formatted on failure: this is the per-value path of the text readers).
double ParseNumberOrThrow(std::string_view token, const std::string& path, int64_t line);
// Lower case copy.
std::string ToLower(std::string_view text);

// The role of a named per-point field.
enum class FieldRole { kOther, kX, kY, kZ, kIntensity, kRed, kGreen, kBlue, kPackedRgb };
FieldRole RoleOfFieldName(const std::string& name);

// Most points one file may declare (8.6e9: ~100 GB of float positions); a header claiming more is
// corrupt. Sizes read from headers are also checked against the file's size before allocating.
constexpr int64_t kMaxPointsPerFile = int64_t{1} << 33;

// A sequential reader of one file's point records, implemented per format.
class PointSource {
 public:
  PointSource(std::string path, const CloudReadOptions& options);
  virtual ~PointSource() = default;
  PointSource(const PointSource&) = delete;
  PointSource& operator=(const PointSource&) = delete;

  const std::string& path() const { return path_; }
  const PointCloudInfo& info() const { return info_; }
  const CloudReadStats& stats() const { return stats_; }
  bool with_intensity() const { return info_.has_intensity && options_.read_intensity; }
  bool with_colour() const { return info_.has_colour && options_.read_colour; }

  // Appends the finite points of up to `max_records` (> 0) more records to *out, whose attribute
  // arrays are sized as with_intensity() / with_colour() say. Returns the number of records
  // consumed, 0 once there are none left.
  virtual int64_t Read(int64_t max_records, PointCloud* out) = 0;
  // Points worth reserving for reading the whole file: the declared count, but never more than
  // the file's size allows (a corrupt count must not allocate a fortune); 0 if unknown.
  int64_t reserve_hint() const { return reserve_hint_; }

 protected:
  // For a binary body of `declared` records of `record_bytes` starting at byte `body_offset`:
  // throws Error "<path>: truncated ..." if the file is too short (or `declared` is negative or
  // beyond kMaxPointsPerFile), else sets reserve_hint().
  void CheckBinaryBody(int64_t declared, uint64_t body_offset, size_t record_bytes);
  // For text with `declared` points: a reserve hint of at most one point per 6 bytes ("0 0 0\n").
  void SetTextReserveHint(int64_t declared);
  // Appends one point unless its position is not finite (counted instead).
  void AddPoint(PointCloud* out,
                double x,
                double y,
                double z,
                float intensity,
                const std::array<uint8_t, 3>& rgb);
  // Decodes records [first, first + count) of a binary body laid out as `layout` says.
  void DecodeRecords(
      const char* data, int64_t first, int64_t count, const RecordLayout& layout, PointCloud* out);
  // Reads exactly `bytes` bytes from `in` into `buffer`, or throws Error "<path>: truncated ..."
  // reporting `records_before` + the complete records read (`record_bytes` each) of `declared`.
  void ReadBody(std::ifstream* in,
                size_t bytes,
                size_t record_bytes,
                int64_t records_before,
                int64_t declared,
                std::vector<char>* buffer);

  std::string path_;
  CloudReadOptions options_;
  PointCloudInfo info_;
  CloudReadStats stats_;
  int64_t reserve_hint_ = 0;

 private:
  std::vector<double> columns_;  // DecodeRecords' scratch
};

// Opens `path` in binary mode or throws Error "<path>: cannot open".
void OpenForReading(const std::string& path, std::ifstream* in);

std::unique_ptr<PointSource> OpenPlySource(const std::string& path,
                                           const CloudReadOptions& options);
std::unique_ptr<PointSource> OpenPcdSource(const std::string& path,
                                           const CloudReadOptions& options);
std::unique_ptr<PointSource> OpenKittiSource(const std::string& path,
                                             const CloudReadOptions& options);
std::unique_ptr<PointSource> OpenXyzSource(const std::string& path,
                                           const CloudReadOptions& options);
std::unique_ptr<PointSource> OpenLasSource(const std::string& path,
                                           const CloudReadOptions& options);
std::unique_ptr<PointSource> OpenSource(const std::string& path, const CloudReadOptions& options);

// Appends little-endian bytes of a value.
void AppendFloatLE(float value, std::string* out);

// Binary little-endian PLY records: x y z float, [intensity float], [red green blue uchar].
size_t PlyRecordBytes(bool with_intensity, bool with_colour);
// The header of such a file (ascii or binary) with `num_points` vertices; with `length` > 0, its
// comment is padded with spaces to make the header exactly `length` bytes (a header rewritten in
// place once the count is known), which must be enough for the count's digits.
std::string PlyHeader(
    int64_t num_points, bool with_intensity, bool with_colour, bool binary, size_t length = 0);
// Appends the binary records of points [begin, end) of `cloud` (with the cloud's attributes).
void AppendPlyRecords(const PointCloud& cloud, size_t begin, size_t end, std::string* out);
// Writes the binary record of point i of `cloud` at `out` (PlyRecordBytes(cloud.HasIntensity(),
// cloud.HasColour()) bytes) and returns the end of it.
char* EncodePlyRecord(const PointCloud& cloud, size_t i, char* out);

void WritePly(const std::string& path, const PointCloud& cloud, bool binary);
void WritePcd(const std::string& path, const PointCloud& cloud, bool binary);
void WriteKittiBin(const std::string& path, const PointCloud& cloud);
void WriteXyz(const std::string& path, const PointCloud& cloud);

// The tile directory's index file name and a tile's file name (tiled_cloud.h).
constexpr const char* kTileIndexName = "tiles.json";
std::string TileFileName(int32_t ix, int32_t iy);
// The tile index of x (or y) for tiles of `tile_size_m`; throws Error when it does not fit 32 bits.
int32_t TileIndex(double coordinate, double tile_size_m);

// Opens `path` for writing (binary, truncating) or throws Error.
void OpenForWriting(const std::string& path, std::ofstream* out);
// Closes `out` and throws Error "<path>: write failed" if anything went wrong.
void CloseOrThrow(const std::string& path, std::ofstream* out);

}  // namespace cloud_internal
}  // namespace epiloc
