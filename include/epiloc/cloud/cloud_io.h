// Reading and writing point-cloud files, whole or streamed in chunks.
//
// Formats (chosen by the file name's extension unless an options struct names one):
//   .ply       PLY 1.0, ascii / binary_little_endian / binary_big_endian. The `vertex` element's
//              x y z (any scalar type), intensity (also named scalar_intensity or reflectance) and
//              red green blue (also r g b, diffuse_red ...) in any order; other properties,
//              elements and comments are skipped. Written as x y z intensity (float) and
//              red green blue (uchar), each attribute only where the cloud has it.
//   .pcd       PCD 0.5-0.7 (PCL), DATA ascii / binary / binary_compressed (LZF; read only).
//              Fields x y z, intensity (also i, reflectance), rgb / rgba packed as 0x00RRGGBB in a
//              4-byte float or uint32; other fields skipped. Written with rgb as uint32.
//   .bin       KITTI Velodyne scan: N records of 4 little-endian float32, x y z reflectance
//              (reflectance, 0..1, becomes intensity).
//   .xyz .txt  text, one point a line: x y z, x y z intensity, x y z r g b or x y z intensity r g b
//              (by the number of columns, colours 0..255), separated by spaces, tabs, commas or
//              semicolons; lines starting with '#' or '//' are comments. A first line of column
//              names (x y z intensity r g b, any case; others skipped) sets the layout instead.
//   .las       ASPRS LAS 1.0-1.4, uncompressed, point formats 0-10 (read only, own reader: Debian
//              bookworm packages no LAS library): scaled x y z, intensity (uint16 / 65535) and
//              colour (uint16 / 257) where the format has it. LAZ (compressed) is refused with
//              a clear error: no Debian package decompresses it.
//
// Conventions on reading, whatever the format:
//   - Positions become float metres. A point whose x, y or z is NaN or infinite (PCL's organised
//     clouds mark invalid points so) is dropped and counted in CloudReadStats::num_non_finite;
//     readers log one warning per file when any were dropped.
//   - Intensity ends up in [0, 1]: 8- and 16-bit unsigned integers are divided by 255 / 65535,
//     any other type is multiplied by CloudReadOptions::float_intensity_scale; values outside
//     [0, 1] (and NaN) are clamped (NaN -> 0) and counted in num_intensity_clamped.
//   - Colours: 8-bit values as they are, 16-bit values / 257, floats in [0, 1] times 255.
//   - Malformed input throws Error naming the file and, for text, the line: not a point cloud,
//     a truncated binary body, no x / y / z, a bad number, an inconsistent header.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "epiloc/cloud/point_cloud.h"

namespace epiloc {

enum class CloudFormat {
  kAuto,      // from the file name's extension
  kPly,       // .ply
  kPcd,       // .pcd
  kKittiBin,  // .bin (KITTI Velodyne)
  kXyz,       // .xyz, .txt
  kLas,       // .las (read only)
};

// "ply", "pcd", "bin", "xyz", "las" ("auto" for kAuto).
std::string CloudFormatName(CloudFormat format);
// The inverse of CloudFormatName (also "kitti", "txt", "laz"); throws Error for another name.
CloudFormat ParseCloudFormat(const std::string& name);
// The format of `path` by its extension (case-insensitive); throws Error naming the path for an
// unknown extension and for .laz.
CloudFormat CloudFormatFromPath(const std::string& path);

struct CloudReadOptions {
  CloudFormat format = CloudFormat::kAuto;  // kAuto: from the file name's extension
  bool read_intensity = true;               // false: leave intensity empty even if the file has it
  bool read_colour = true;                  // false: leave rgb empty even if the file has it
  double float_intensity_scale = 1.0;       // multiplies float / wide-integer intensities before
                                            // clamping to [0, 1] (1/255 for clouds storing 0..255)
  // Throws Error naming the first invalid field.
  void Check() const;
};

// What a file's header says, without reading the points.
struct PointCloudInfo {
  CloudFormat format = CloudFormat::kAuto;
  std::string encoding;     // "ascii", "binary_little_endian", "binary_big_endian", "binary",
                            // "binary_compressed", "text", "float32"
  int64_t num_points = -1;  // point records the file declares (before dropping non-finite
                            // points); -1 where the format does not say (XYZ text)
  bool has_intensity = false;
  bool has_colour = false;
  std::vector<std::string> fields;  // per-point fields in file order (as the file names them)
  Bounds3f bounds;                  // from the header where it has them (LAS), else empty
};

// Figures of one read.
struct CloudReadStats {
  int64_t num_records = 0;            // point records read from the file
  int64_t num_points = 0;             // points returned (records minus the dropped ones)
  int64_t num_non_finite = 0;         // records dropped: x, y or z NaN or infinite
  int64_t num_intensity_clamped = 0;  // intensities outside [0, 1] or NaN after scaling
};

// Reads the header of `path`. Throws Error as ReadPointCloud does.
PointCloudInfo ReadPointCloudHeader(const std::string& path,
                                    const CloudReadOptions& options = CloudReadOptions());

// Reads a whole point-cloud file (format by extension or options.format). Non-finite points are
// dropped; `stats` (optional) receives the figures. Throws Error for an unreadable or malformed
// file (naming it, and the line for text formats).
PointCloud ReadPointCloud(const std::string& path,
                          const CloudReadOptions& options = CloudReadOptions(),
                          CloudReadStats* stats = nullptr);

namespace cloud_internal {
class PointSource;
}  // namespace cloud_internal

// A sequential reader that hands out a file's points in chunks, so files larger than memory can
// be processed: only one chunk (and a bounded read buffer) is held at a time. PCD
// binary_compressed is the exception: its body is decompressed whole.
class PointCloudReader {
 public:
  // Opens `path` and reads its header; throws Error as ReadPointCloud does.
  explicit PointCloudReader(const std::string& path,
                            const CloudReadOptions& options = CloudReadOptions());
  ~PointCloudReader();
  PointCloudReader(PointCloudReader&&) noexcept;
  PointCloudReader& operator=(PointCloudReader&&) noexcept;

  const std::string& path() const { return path_; }
  const PointCloudInfo& info() const;
  // Replaces *chunk by the next up to `max_points` (> 0) points; false (and an empty chunk) once
  // no point is left. The chunk has intensity / colour where the file has them and the options
  // ask for them. Throws Error for malformed data.
  bool ReadChunk(int64_t max_points, PointCloud* chunk);
  // Figures so far.
  const CloudReadStats& stats() const;

 private:
  std::string path_;
  std::unique_ptr<cloud_internal::PointSource> source_;
  bool finished_ = false;
};

// Calls `callback` with consecutive chunks of at most `chunk_points` points of `path` (memory is
// bounded by the chunk, whatever the file's size) and returns the figures. Exceptions from the
// callback propagate. Throws Error as ReadPointCloud does.
CloudReadStats ForEachPointChunk(const std::string& path,
                                 int64_t chunk_points,
                                 const std::function<void(const PointCloud& chunk)>& callback,
                                 const CloudReadOptions& options = CloudReadOptions());

struct CloudWriteOptions {
  CloudFormat format = CloudFormat::kAuto;  // kAuto: from the extension; PLY, PCD, XYZ or KITTI
  bool binary = true;  // PLY binary_little_endian / PCD binary; false: ascii. XYZ is always
                       // text and KITTI .bin always binary.
  // Throws Error naming the first invalid field (kLas: not writable).
  void Check() const;
};

// Writes `cloud` to `path` with the attributes it has (KITTI .bin: intensity 0 where the cloud
// has none, colour dropped). Text is written with the shortest digits that read back as the same
// float, so ascii round trips are exact. Throws Error if the file cannot be written or the cloud
// is inconsistent.
void WritePointCloud(const std::string& path,
                     const PointCloud& cloud,
                     const CloudWriteOptions& options = CloudWriteOptions());

}  // namespace epiloc
