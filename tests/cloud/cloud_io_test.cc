#include "epiloc/cloud/cloud_io.h"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <new>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cloud_test_util.h"
#include "test_util.h"

namespace epiloc {
namespace {

using ::testing::HasSubstr;

const std::string kFixtureDir = std::string(EPILOC_SOURCE_DIR) + "/tests/cloud/data";

struct Attributes {
  bool intensity;
  bool colour;
};
const Attributes kAllAttributes[] = {{false, false}, {true, false}, {false, true}, {true, true}};

TEST(PointCloud, AppendFillsAndAdoptsAttributes) {
  PointCloud a = RandomCloud(3, 1, true, false);
  const PointCloud b = RandomCloud(2, 2, false, false);
  a.Append(b);
  ASSERT_EQ(a.size(), 5u);
  EXPECT_EQ(a.intensity[4], 0.0f);
  PointCloud empty;
  empty.Append(RandomCloud(2, 3, true, true));
  EXPECT_TRUE(empty.HasIntensity() && empty.HasColour());
  PointCloud c = RandomCloud(2, 4, true, true);
  c.Append(RandomCloud(1, 5, false, false));
  EXPECT_EQ(c.rgb[2], (std::array<uint8_t, 3>{128, 128, 128}));
  PointCloud plain = RandomCloud(2, 6, false, false);
  ExpectError([&] { plain.Append(RandomCloud(1, 7, true, false)); }, {"intensity"});
  PointCloud broken = RandomCloud(2, 8, false, false);
  broken.intensity.push_back(0.5f);
  ExpectError([&] { broken.Check(); }, {"1 intensities for 2 points"});
  const Bounds3f bounds = ComputeBounds(RandomCloud(100, 9, false, false));
  EXPECT_FALSE(bounds.Empty());
  EXPECT_TRUE(ComputeBounds(PointCloud()).Empty());
}

TEST(CloudIo, FormatNames) {
  EXPECT_EQ(CloudFormatFromPath("a/b/Map.PLY"), CloudFormat::kPly);
  EXPECT_EQ(CloudFormatFromPath("x.pcd"), CloudFormat::kPcd);
  EXPECT_EQ(CloudFormatFromPath("0000.bin"), CloudFormat::kKittiBin);
  EXPECT_EQ(CloudFormatFromPath("p.txt"), CloudFormat::kXyz);
  EXPECT_EQ(CloudFormatFromPath("p.las"), CloudFormat::kLas);
  EXPECT_EQ(ParseCloudFormat("kitti"), CloudFormat::kKittiBin);
  EXPECT_EQ(ParseCloudFormat(CloudFormatName(CloudFormat::kPcd)), CloudFormat::kPcd);
  ExpectError([] { CloudFormatFromPath("scan.obj"); }, {"scan.obj", "unknown", "'obj'"});
  ExpectError([] { CloudFormatFromPath("scan.laz"); }, {"scan.laz", "LAZ"});
  ExpectError([] { ParseCloudFormat("e57"); }, {"e57"});
}

TEST(CloudIo, PlyAndPcdRoundTrips) {
  TempDir dir;
  int seed = 10;
  for (const Attributes& a : kAllAttributes) {
    const PointCloud cloud = RandomCloud(1000, ++seed, a.intensity, a.colour);
    for (const std::string ext : {"ply", "pcd"}) {
      for (bool binary : {true, false}) {
        SCOPED_TRACE(ext + (binary ? " binary" : " ascii") + " intensity " +
                     std::to_string(a.intensity) + " colour " + std::to_string(a.colour));
        const std::string path = dir / ("cloud." + ext);
        WritePointCloud(path, cloud, CloudWriteOptions{CloudFormat::kAuto, binary});
        const PointCloudInfo info = ReadPointCloudHeader(path);
        EXPECT_EQ(info.num_points, 1000);
        EXPECT_EQ(info.has_intensity, a.intensity);
        EXPECT_EQ(info.has_colour, a.colour);
        // The shortest round-trip digits make even text exact.
        CloudReadStats stats;
        ExpectSameCloud(cloud, ReadPointCloud(path, CloudReadOptions(), &stats));
        EXPECT_EQ(stats.num_points, 1000);
        EXPECT_EQ(stats.num_non_finite, 0);
      }
    }
  }
}

TEST(CloudIo, KittiAndXyzRoundTrips) {
  TempDir dir;
  const PointCloud cloud = RandomCloud(500, 20, true, false);
  WritePointCloud(dir / "scan.bin", cloud);
  EXPECT_EQ(std::filesystem::file_size(dir / "scan.bin"), 500u * 16);
  ExpectSameCloud(cloud, ReadPointCloud(dir / "scan.bin"));
  for (const Attributes& a : kAllAttributes) {
    const PointCloud text = RandomCloud(300, 21, a.intensity, a.colour);
    WritePointCloud(dir / "points.xyz", text);
    ExpectSameCloud(text, ReadPointCloud(dir / "points.xyz"));
  }
  // Without intensity the KITTI writer stores 0.
  WritePointCloud(dir / "plain.bin", RandomCloud(3, 22, false, true));
  EXPECT_EQ(ReadPointCloud(dir / "plain.bin").intensity, std::vector<float>(3, 0.0f));
}

TEST(CloudIo, ReadsKittiScanBytes) {
  TempDir dir;
  std::string bytes;
  for (float v : {1.5f, -2.0f, 0.25f, 0.5f, 10.0f, 20.0f, -1.0f, 1.0f}) PutBytes(v, false, &bytes);
  WriteBytes(dir / "0000000000.bin", bytes);
  const PointCloud cloud = ReadPointCloud(dir / "0000000000.bin");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[0], Eigen::Vector3f(1.5f, -2.0f, 0.25f));
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(10.0f, 20.0f, -1.0f));
  EXPECT_EQ(cloud.intensity, (std::vector<float>{0.5f, 1.0f}));
  WriteBytes(dir / "bad.bin", bytes.substr(0, 20));
  ExpectError([&] { ReadPointCloud(dir / "bad.bin"); },
              {dir / "bad.bin", "not a KITTI Velodyne scan", "20 bytes"});
}

TEST(CloudIo, ReadsRealKittiScan) {
  const std::string path = (KittiRawDrive() / "velodyne_points/data/0000000000.bin").string();
  EPILOC_SKIP_UNLESS_EXISTS(path);
  CloudReadStats stats;
  const PointCloud cloud = ReadPointCloud(path, CloudReadOptions(), &stats);
  EXPECT_EQ(stats.num_records, static_cast<int64_t>(std::filesystem::file_size(path) / 16));
  // The shared copy keeps the points in front of the car (x > 0) within 80 m of a 64-beam scan.
  EXPECT_GT(cloud.size(), 30000u);
  EXPECT_EQ(stats.num_intensity_clamped, 0);
  const Bounds3f bounds = ComputeBounds(cloud);
  EXPECT_GE(bounds.min.x(), 0.0f);
  EXPECT_GT(bounds.max.x(), 40.0f);
  EXPECT_LT(bounds.min.z(), -1.5f);  // the road, 1.73 m below the sensor
  float max_range = 0;
  int near_ground = 0;
  for (const Eigen::Vector3f& p : cloud.positions) {
    max_range = std::max(max_range, p.norm());
    near_ground += std::abs(p.z() + 1.73f) < 0.3f;
  }
  EXPECT_LT(max_range, 80.5f);
  EXPECT_GT(near_ground, static_cast<int>(cloud.size() / 10));
}

TEST(CloudIo, PlyFixtureWithFacesAndExtraProperties) {
  const std::string path = kFixtureDir + "/mesh_with_faces.ply";
  const PointCloudInfo info = ReadPointCloudHeader(path);
  EXPECT_EQ(info.num_points, 4);
  EXPECT_EQ(info.encoding, "ascii");
  EXPECT_TRUE(info.has_intensity);
  EXPECT_TRUE(info.has_colour);
  EXPECT_EQ(info.fields.size(), 11u);
  const PointCloud cloud = ReadPointCloud(path);
  ASSERT_EQ(cloud.size(), 4u);
  EXPECT_EQ(cloud.positions[0], Eigen::Vector3f(10.0f, -2.25f, 1.5f));
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(-3.75f, 0.0f, -0.5f));
  EXPECT_EQ(cloud.positions[3], Eigen::Vector3f(0.125f, 1000.0f, 2.0f));
  EXPECT_FLOAT_EQ(cloud.intensity[0], 1.0f);  // ushort rescaled by 65535
  EXPECT_FLOAT_EQ(cloud.intensity[2], 0.2f);
  EXPECT_EQ(cloud.rgb[1], (std::array<uint8_t, 3>{0, 128, 255}));
  EXPECT_EQ(cloud.rgb[3], (std::array<uint8_t, 3>{9, 8, 7}));
  CloudReadOptions no_attributes;
  no_attributes.read_intensity = false;
  no_attributes.read_colour = false;
  const PointCloud bare = ReadPointCloud(path, no_attributes);
  EXPECT_FALSE(bare.HasIntensity() || bare.HasColour());
  EXPECT_EQ(bare.size(), 4u);
}

// A big-endian binary PLY with an element (with a list) before the vertices, a list inside the
// vertex, mixed scalar types, and faces after.
TEST(CloudIo, BigEndianPlyWithListsAndOtherElements) {
  TempDir dir;
  std::string bytes =
      "ply\r\nformat binary_big_endian 1.0\r\ncomment CRLF header\r\n"
      "element camera 2\r\nproperty list uchar short params\r\nproperty int id\r\n"
      "element vertex 3\r\nproperty uchar reflectance\r\nproperty double x\r\n"
      "property list ushort uchar tags\r\nproperty int y\r\nproperty float z\r\n"
      "property uchar blue\r\nproperty uchar green\r\nproperty uchar red\r\n"
      "element face 1\r\nproperty list uchar uint vertex_indices\r\nend_header\r\n";
  // Cameras: 1 and 3 list items.
  PutBytes<uint8_t>(1, true, &bytes);
  PutBytes<int16_t>(-7, true, &bytes);
  PutBytes<int32_t>(1, true, &bytes);
  PutBytes<uint8_t>(3, true, &bytes);
  for (int16_t v : {1, 2, 3}) PutBytes(v, true, &bytes);
  PutBytes<int32_t>(2, true, &bytes);
  const double xs[] = {1.25, -1e6, 0.0};
  const int32_t ys[] = {-3, 4, 123456};
  const float zs[] = {0.5f, std::numeric_limits<float>::quiet_NaN(), 2.0f};
  for (int i = 0; i < 3; ++i) {
    PutBytes<uint8_t>(static_cast<uint8_t>(51 * i), true, &bytes);
    PutBytes(xs[i], true, &bytes);
    PutBytes<uint16_t>(static_cast<uint16_t>(i), true, &bytes);
    bytes.append(static_cast<size_t>(i), 'T');
    PutBytes(ys[i], true, &bytes);
    PutBytes(zs[i], true, &bytes);
    bytes += static_cast<char>(10 * i + 3);  // blue
    bytes += static_cast<char>(10 * i + 2);  // green
    bytes += static_cast<char>(10 * i + 1);  // red
  }
  PutBytes<uint8_t>(3, true, &bytes);
  for (uint32_t v : {0u, 1u, 2u}) PutBytes(v, true, &bytes);
  WriteBytes(dir / "be.ply", bytes);

  CloudReadStats stats;
  const PointCloud cloud = ReadPointCloud(dir / "be.ply", CloudReadOptions(), &stats);
  // The NaN point is dropped and counted.
  EXPECT_EQ(stats.num_records, 3);
  EXPECT_EQ(stats.num_non_finite, 1);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.positions[0], Eigen::Vector3f(1.25f, -3.0f, 0.5f));
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(0.0f, 123456.0f, 2.0f));
  EXPECT_FLOAT_EQ(cloud.intensity[0], 0.0f);
  EXPECT_FLOAT_EQ(cloud.intensity[1], 0.4f);  // uint8 / 255
  EXPECT_EQ(cloud.rgb[1], (std::array<uint8_t, 3>{21, 22, 23}));

  // Truncated inside the vertices.
  WriteBytes(dir / "cut.ply", bytes.substr(0, bytes.size() - 40));
  ExpectError([&] { ReadPointCloud(dir / "cut.ply"); }, {dir / "cut.ply", "truncated"});
}

TEST(CloudIo, IntensityScalingAndClamping) {
  TempDir dir;
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nproperty float intensity\nend_header\n";
  WriteText(dir / "i.ply", header + "0 0 0 0.5\n1 1 1 255\n2 2 2 -1\n");
  CloudReadStats stats;
  EXPECT_EQ(ReadPointCloud(dir / "i.ply", CloudReadOptions(), &stats).intensity,
            (std::vector<float>{0.5f, 1.0f, 0.0f}));
  EXPECT_EQ(stats.num_intensity_clamped, 2);
  CloudReadOptions scaled;
  scaled.float_intensity_scale = 1.0 / 255.0;
  const PointCloud cloud = ReadPointCloud(dir / "i.ply", scaled, &stats);
  EXPECT_FLOAT_EQ(cloud.intensity[1], 1.0f);
  EXPECT_FLOAT_EQ(cloud.intensity[0], 0.5f / 255.0f);
  EXPECT_EQ(stats.num_intensity_clamped, 1);
  scaled.float_intensity_scale = 0;
  ExpectError([&] { ReadPointCloud(dir / "i.ply", scaled); }, {"float_intensity_scale"});
}

TEST(CloudIo, PlyErrors) {
  TempDir dir;
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  WriteText(dir / "bad_number.ply", header + "1 2 3\n4 five 6\n");
  ExpectError([&] { ReadPointCloud(dir / "bad_number.ply"); },
              {dir / "bad_number.ply" + ":9", "'five' is not a number"});
  WriteText(dir / "short.ply", header + "1 2 3\n4 5\n");
  ExpectError([&] { ReadPointCloud(dir / "short.ply"); }, {dir / "short.ply" + ":9", "too few"});
  WriteText(dir / "long.ply", header + "1 2 3 4\n");
  ExpectError([&] { ReadPointCloud(dir / "long.ply"); }, {dir / "long.ply" + ":8", "4 values"});
  WriteText(dir / "few.ply", header + "1 2 3\n");
  ExpectError([&] { ReadPointCloud(dir / "few.ply"); }, {dir / "few.ply", "truncated", "after 1"});
  WriteText(dir / "magic.ply", "PLY\nformat ascii 1.0\n");
  ExpectError([&] { ReadPointCloud(dir / "magic.ply"); }, {dir / "magic.ply", "not a PLY"});
  WriteText(dir / "empty.ply", "");
  ExpectError([&] { ReadPointCloud(dir / "empty.ply"); }, {dir / "empty.ply", "not a PLY"});
  WriteText(dir / "no_x.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\n"
            "property float z\nend_header\n1 2\n");
  ExpectError([&] { ReadPointCloud(dir / "no_x.ply"); }, {dir / "no_x.ply", "no 'x'"});
  WriteText(dir / "no_vertex.ply",
            "ply\nformat ascii 1.0\nelement face 0\n"
            "property list uchar int vertex_indices\nend_header\n");
  ExpectError([&] { ReadPointCloud(dir / "no_vertex.ply"); },
              {dir / "no_vertex.ply", "not a point cloud"});
  WriteText(dir / "no_end.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n");
  ExpectError([&] { ReadPointCloud(dir / "no_end.ply"); }, {dir / "no_end.ply", "end_header"});
  WriteText(dir / "type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\n");
  ExpectError([&] { ReadPointCloud(dir / "type.ply"); }, {dir / "type.ply:4", "float128"});
  WriteText(dir / "format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n");
  ExpectError([&] { ReadPointCloud(dir / "format.ply"); }, {dir / "format.ply:2", "middle"});
  ExpectError([&] { ReadPointCloud(dir / "missing.ply"); }, {dir / "missing.ply", "cannot open"});
  ExpectError([&] { ReadPointCloud(dir.str(), CloudReadOptions{CloudFormat::kPly}); },
              {"is a directory"});

  // A corrupt huge count is reported, not allocated.
  for (const std::string encoding : {"binary_little_endian", "ascii"}) {
    WriteText(dir / "huge.ply", "ply\nformat " + encoding +
                                    " 1.0\nelement vertex 999999999999\nproperty float x\n"
                                    "property float y\nproperty float z\nend_header\n0 0 0\n");
    ExpectError([&] { ReadPointCloud(dir / "huge.ply"); },
                {dir / "huge.ply", "truncated", "declares 999999999999 points"});
  }

  // A truncated binary body: the file ends inside the last point.
  WritePointCloud(dir / "cut.ply", RandomCloud(10, 30, true, true));
  std::filesystem::resize_file(dir / "cut.ply", std::filesystem::file_size(dir / "cut.ply") - 5);
  ExpectError([&] { ReadPointCloud(dir / "cut.ply"); },
              {dir / "cut.ply", "truncated", "declares 10 points", "after 9"});
}

TEST(CloudIo, PcdFromPclWithOrganisedNanAndPadding) {
  TempDir dir;
  // PCL's PointXYZRGBNormal-like layout: float rgb, a COUNT 3 field, padding, organised 2 x 2.
  float rgb_float;
  const uint32_t packed = (10u << 16) | (20u << 8) | 30u;
  std::memcpy(&rgb_float, &packed, 4);
  char rgb_text[64];
  std::snprintf(rgb_text, sizeof(rgb_text), "%.9g", rgb_float);
  WriteText(dir / "pcl.pcd",
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
            "FIELDS x y z rgb normal _ intensity\nSIZE 4 4 4 4 4 1 2\nTYPE F F F F F U U\n"
            "COUNT 1 1 1 1 3 1 1\nWIDTH 2\nHEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\n"
            "DATA ascii\n1 2 3 " +
                std::string(rgb_text) + " 0 0 1 0 65535\n" + "nan nan nan 0 0 0 1 0 0\n\n" +
                "-1 -2 -3 " + rgb_text + " 0 1 0 0 13107\n" + "4 5 6 0 1 0 0 0 0\n");
  const PointCloudInfo info = ReadPointCloudHeader(dir / "pcl.pcd");
  EXPECT_EQ(info.num_points, 4);
  EXPECT_TRUE(info.has_colour);
  CloudReadStats stats;
  const PointCloud cloud = ReadPointCloud(dir / "pcl.pcd", CloudReadOptions(), &stats);
  EXPECT_EQ(stats.num_non_finite, 1);
  ASSERT_EQ(cloud.size(), 3u);
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(-1, -2, -3));
  EXPECT_EQ(cloud.rgb[0], (std::array<uint8_t, 3>{10, 20, 30}));
  EXPECT_FLOAT_EQ(cloud.intensity[0], 1.0f);  // uint16 / 65535
  EXPECT_FLOAT_EQ(cloud.intensity[1], 0.2f);

  // The same as binary, then truncated.
  std::string bytes =
      "VERSION .7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n"
      "DATA binary\n";
  for (float v : {1.0f, 2.0f, 3.0f, rgb_float, 4.0f, 5.0f, 6.0f, rgb_float}) {
    PutBytes(v, false, &bytes);
  }
  WriteBytes(dir / "bin.pcd", bytes);
  const PointCloud binary = ReadPointCloud(dir / "bin.pcd");
  ASSERT_EQ(binary.size(), 2u);
  EXPECT_EQ(binary.positions[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(binary.rgb[1], (std::array<uint8_t, 3>{10, 20, 30}));
  WriteBytes(dir / "cut.pcd", bytes.substr(0, bytes.size() - 1));
  ExpectError([&] { ReadPointCloud(dir / "cut.pcd"); }, {dir / "cut.pcd", "truncated", "after 1"});
}

// liblzf-format compressor (greedy, brute-force search) for building test files.
std::string LzfCompress(const std::string& in) {
  std::string out;
  std::string literal;
  auto flush = [&] {
    for (size_t k = 0; k < literal.size(); k += 32) {
      const std::string run = literal.substr(k, 32);
      out += static_cast<char>(run.size() - 1);
      out += run;
    }
    literal.clear();
  };
  size_t i = 0;
  while (i < in.size()) {
    size_t best_length = 0;
    size_t best_distance = 0;
    for (size_t d = 1; d <= std::min<size_t>(i, 8192); ++d) {
      size_t length = 0;
      while (length < 264 && i + length < in.size() && in[i - d + length] == in[i + length]) {
        ++length;
      }
      if (length > best_length) {
        best_length = length;
        best_distance = d;
      }
    }
    if (best_length < 3) {
      literal += in[i++];
      continue;
    }
    flush();
    const size_t length = best_length - 2;
    const size_t offset = best_distance - 1;
    out += static_cast<char>((std::min<size_t>(length, 7) << 5) | (offset >> 8));
    if (length >= 7) out += static_cast<char>(length - 7);
    out += static_cast<char>(offset & 0xff);
    i += best_length;
  }
  flush();
  return out;
}

TEST(CloudIo, PcdBinaryCompressed) {
  TempDir dir;
  PointCloud cloud = RandomCloud(200, 40, true, false);
  for (size_t i = 100; i < 200; ++i) cloud.positions[i].z() = 1.0f;  // compressible runs
  // Field by field: all x, all y, all z, all intensity.
  std::string body;
  for (int field = 0; field < 4; ++field) {
    for (size_t i = 0; i < cloud.size(); ++i) {
      PutBytes(field < 3 ? cloud.positions[i][field] : cloud.intensity[i], false, &body);
    }
  }
  const std::string compressed = LzfCompress(body);
  ASSERT_LT(compressed.size(), body.size());
  const std::string header =
      "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
      "WIDTH 200\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 200\nDATA binary_compressed\n";
  std::string bytes = header;
  PutBytes(static_cast<uint32_t>(compressed.size()), false, &bytes);
  PutBytes(static_cast<uint32_t>(body.size()), false, &bytes);
  WriteBytes(dir / "c.pcd", bytes + compressed);
  EXPECT_EQ(ReadPointCloudHeader(dir / "c.pcd").encoding, "binary_compressed");
  ExpectSameCloud(cloud, ReadPointCloud(dir / "c.pcd"));
  // Chunked reading hands out the same points.
  PointCloud chunks;
  ForEachPointChunk(dir / "c.pcd", 33, [&](const PointCloud& chunk) { chunks.Append(chunk); });
  ExpectSameCloud(cloud, chunks);

  WriteBytes(dir / "short.pcd", bytes + compressed.substr(0, compressed.size() - 3));
  ExpectError([&] { ReadPointCloud(dir / "short.pcd"); }, {dir / "short.pcd", "truncated"});
  std::string corrupt = compressed;
  corrupt[0] = static_cast<char>(0xe0);  // a back reference before the start
  WriteBytes(dir / "corrupt.pcd", bytes + corrupt);
  ExpectError([&] { ReadPointCloud(dir / "corrupt.pcd"); }, {dir / "corrupt.pcd", "LZF"});
}

TEST(CloudIo, PcdErrors) {
  TempDir dir;
  WriteText(dir / "garbage.pcd", "hello\n");
  ExpectError([&] { ReadPointCloud(dir / "garbage.pcd"); }, {dir / "garbage.pcd", "not a PCD"});
  WriteText(dir / "no_data.pcd", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\n");
  ExpectError([&] { ReadPointCloud(dir / "no_data.pcd"); }, {dir / "no_data.pcd", "no DATA"});
  WriteText(dir / "size.pcd", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4\n");
  ExpectError([&] { ReadPointCloud(dir / "size.pcd"); }, {dir / "size.pcd:3", "2 entries"});
  const std::string xy = "VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nPOINTS 1\n";
  WriteText(dir / "no_z.pcd", xy + "DATA ascii\n1 2\n");
  ExpectError([&] { ReadPointCloud(dir / "no_z.pcd"); }, {dir / "no_z.pcd", "no field 'z'"});
  const std::string xyz = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 2\n";
  WriteText(dir / "number.pcd", xyz + "DATA ascii\n1 2 3\n1 2 x3\n");
  ExpectError([&] { ReadPointCloud(dir / "number.pcd"); },
              {dir / "number.pcd:8", "'x3' is not a number"});
  WriteText(dir / "columns.pcd", xyz + "DATA ascii\n1 2 3 4\n");
  ExpectError([&] { ReadPointCloud(dir / "columns.pcd"); }, {dir / "columns.pcd:7", "4 values"});
  WriteText(dir / "points.pcd",
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 3\n"
            "DATA ascii\n");
  ExpectError([&] { ReadPointCloud(dir / "points.pcd"); }, {dir / "points.pcd", "POINTS 3"});
  WriteText(dir / "type.pcd", "FIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nWIDTH 0\nDATA ascii\n");
  ExpectError([&] { ReadPointCloud(dir / "type.pcd"); }, {dir / "type.pcd", "'z'", "SIZE 2"});
}

TEST(CloudIo, XyzText) {
  TempDir dir;
  WriteText(dir / "a.xyz", "# comment\n1 2 3\n\n4.5\t-5 6e1\n// another\n+7 8 9\n");
  PointCloud cloud = ReadPointCloud(dir / "a.xyz");
  ASSERT_EQ(cloud.size(), 3u);
  EXPECT_FALSE(cloud.HasIntensity() || cloud.HasColour());
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(4.5f, -5.0f, 60.0f));
  WriteText(dir / "b.txt", "1,2,3,0.5,10,20,30\r\n4;5;6;0.25;0;0;255\r\n");
  cloud = ReadPointCloud(dir / "b.txt");
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.intensity, (std::vector<float>{0.5f, 0.25f}));
  EXPECT_EQ(cloud.rgb[1], (std::array<uint8_t, 3>{0, 0, 255}));
  // Named columns in any order; unknown ones skipped.
  WriteText(dir / "c.xyz", "Intensity, Z, time, Y, X\n0.75, 3, 99, 2, 1\n");
  cloud = ReadPointCloud(dir / "c.xyz");
  ASSERT_EQ(cloud.size(), 1u);
  EXPECT_EQ(cloud.positions[0], Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(cloud.intensity[0], 0.75f);
  EXPECT_EQ(ReadPointCloudHeader(dir / "c.xyz").num_points, -1);
  // Non-finite points are dropped.
  WriteText(dir / "nan.xyz", "1 2 3\nnan 0 0\n0 inf 0\n");
  CloudReadStats stats;
  EXPECT_EQ(ReadPointCloud(dir / "nan.xyz", CloudReadOptions(), &stats).size(), 1u);
  EXPECT_EQ(stats.num_non_finite, 2);
  WriteText(dir / "empty.xyz", "# nothing\n");
  EXPECT_TRUE(ReadPointCloud(dir / "empty.xyz").empty());
}

TEST(CloudIo, XyzErrors) {
  TempDir dir;
  WriteText(dir / "n.xyz", "1 2 3\n4 5 6\n7 eight 9\n");
  ExpectError([&] { ReadPointCloud(dir / "n.xyz"); }, {dir / "n.xyz:3", "'eight' is not a number"});
  WriteText(dir / "c.xyz", "1 2 3\n4 5\n");
  ExpectError([&] { ReadPointCloud(dir / "c.xyz"); }, {dir / "c.xyz:2", "2 columns"});
  WriteText(dir / "five.xyz", "1 2 3 4 5\n");
  ExpectError([&] { ReadPointCloud(dir / "five.xyz"); }, {dir / "five.xyz:1", "5 columns"});
  WriteText(dir / "normals.xyz", "1 2 3 0.6 0 0.8\n");
  ExpectError([&] { ReadPointCloud(dir / "normals.xyz"); },
              {dir / "normals.xyz:1", "not an integer in 0..255", "column 4"});
  WriteText(dir / "names.xyz", "a b c\n1 2 3\n");
  ExpectError([&] { ReadPointCloud(dir / "names.xyz"); }, {dir / "names.xyz:1", "lack x"});
}

// A LAS file of `points` (X Y Z raw integers, intensity, r g b) in point format `format`.
std::string LasFile(int minor, int format, const std::vector<std::array<int32_t, 7>>& points) {
  const size_t header_bytes = minor >= 4 ? 375 : 227;
  const size_t record_bytes[] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  const size_t rgb_offset[] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};
  std::string header(header_bytes, '\0');
  auto put = [&](size_t at, auto value) { std::memcpy(&header[at], &value, sizeof(value)); };
  header.replace(0, 4, "LASF");
  header[24] = 1;
  header[25] = static_cast<char>(minor);
  put(94, static_cast<uint16_t>(header_bytes));
  put(96, static_cast<uint32_t>(header_bytes));
  header[104] = static_cast<char>(format);
  put(105, static_cast<uint16_t>(record_bytes[format] + 2));  // 2 extra bytes per record
  put(107, static_cast<uint32_t>(format < 6 ? points.size() : 0));
  for (int k = 0; k < 3; ++k) {
    put(131 + 8 * k, 0.01);        // scale
    put(155 + 8 * k, 1000.0 * k);  // offset
    put(179 + 16 * k, 99.0);       // max
    put(187 + 16 * k, -99.0);      // min
  }
  if (minor >= 4) put(247, static_cast<uint64_t>(points.size()));
  std::string bytes = header;
  for (const auto& p : points) {
    std::string record(record_bytes[format] + 2, '\x55');
    std::memcpy(&record[0], &p[0], 12);
    const auto intensity = static_cast<uint16_t>(p[3]);
    std::memcpy(&record[12], &intensity, 2);
    if (rgb_offset[format] != 0) {
      for (int c = 0; c < 3; ++c) {
        const auto value = static_cast<uint16_t>(p[4 + c]);
        std::memcpy(&record[rgb_offset[format] + 2 * c], &value, 2);
      }
    }
    bytes += record;
  }
  return bytes;
}

TEST(CloudIo, Las) {
  TempDir dir;
  const std::vector<std::array<int32_t, 7>> points = {{150, -250, 1000, 65535, 65535, 0, 257},
                                                      {-1, 2, -3, 13107, 0, 32896, 0}};
  for (const auto& [minor, format] : {std::pair{2, 2}, {2, 0}, {4, 7}, {4, 6}, {3, 3}}) {
    SCOPED_TRACE("LAS 1." + std::to_string(minor) + " format " + std::to_string(format));
    WriteBytes(dir / "p.las", LasFile(minor, format, points));
    const PointCloudInfo info = ReadPointCloudHeader(dir / "p.las");
    EXPECT_EQ(info.num_points, 2);
    EXPECT_EQ(info.bounds.min, Eigen::Vector3f::Constant(-99.0f));
    const PointCloud cloud = ReadPointCloud(dir / "p.las");
    ASSERT_EQ(cloud.size(), 2u);
    EXPECT_FLOAT_EQ(cloud.positions[0].x(), 1.5f);
    EXPECT_FLOAT_EQ(cloud.positions[0].y(), 997.5f);
    EXPECT_FLOAT_EQ(cloud.positions[0].z(), 2010.0f);
    EXPECT_FLOAT_EQ(cloud.positions[1].z(), 1999.97f);
    EXPECT_FLOAT_EQ(cloud.intensity[1], 0.2f);
    const bool colour = format == 2 || format == 3 || format == 7;
    ASSERT_EQ(cloud.HasColour(), colour);
    if (colour) {
      EXPECT_EQ(cloud.rgb[0], (std::array<uint8_t, 3>{255, 0, 1}));
      EXPECT_EQ(cloud.rgb[1], (std::array<uint8_t, 3>{0, 128, 0}));
    }
  }
  std::string laz = LasFile(2, 3, points);
  laz[104] = static_cast<char>(3 | 0x80);
  WriteBytes(dir / "z.las", laz);
  ExpectError([&] { ReadPointCloud(dir / "z.las"); }, {dir / "z.las", "LAZ"});
  WriteBytes(dir / "cut.las", LasFile(2, 2, points).substr(0, 227 + 40));
  ExpectError([&] { ReadPointCloud(dir / "cut.las"); }, {dir / "cut.las", "truncated"});
  WriteText(dir / "text.las", "not las");
  ExpectError([&] { ReadPointCloud(dir / "text.las"); }, {dir / "text.las", "LASF"});
  ExpectError([&] { WritePointCloud(dir / "out.las", RandomCloud(1, 1, false, false)); },
              {"out.las", "cannot write point clouds as las"});
}

// Runs `read` in a child process whose address space may grow by at most 256 MB: a reader that
// allocates what a corrupt header claims dies of bad_alloc there (exit 3) instead of failing
// with Error (exit 0). Without the limit (sanitizer builds reserve terabytes of shadow memory) it
// runs `read` in this process.
int ExitCodeUnderMemoryLimit(const std::function<void()>& read) {
  constexpr bool kLimit = !kAddressSanitizer;
  const auto classify = [&] {
    try {
      read();
      return 1;  // no error at all
    } catch (const Error&) {
      return 0;
    } catch (const std::bad_alloc&) {
      return 3;
    } catch (...) {
      return 4;
    }
  };
  if (!kLimit) return classify();
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::ifstream status("/proc/self/statm");
    long pages = 0;
    status >> pages;
    const rlim_t limit = static_cast<rlim_t>(pages) * ::sysconf(_SC_PAGESIZE) + (256u << 20);
    const rlimit rl{limit, limit};
    ::setrlimit(RLIMIT_AS, &rl);
    ::_exit(classify());
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 5;
}

// Issue 18 item 4: sizes from file headers are checked against the file before allocating.
TEST(CloudIo, HeaderSizesAreCheckedBeforeAllocating) {
  TempDir dir;
  // A 1 kB binary_compressed PCD whose size header claims 4 GB (render allocated 4.3 GB).
  std::string pcd =
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 357913941\nHEIGHT 1\n"
      "POINTS 357913941\nDATA binary_compressed\n";
  PutBytes(static_cast<uint32_t>(4294967292u), false, &pcd);
  PutBytes(static_cast<uint32_t>(4294967292u), false, &pcd);
  pcd += std::string(1024, '\x01');
  WriteBytes(dir / "bomb.pcd", pcd);
  EXPECT_EQ(ExitCodeUnderMemoryLimit([&] { ReadPointCloud(dir / "bomb.pcd"); }), 0);
  ExpectError([&] { ReadPointCloud(dir / "bomb.pcd"); }, {dir / "bomb.pcd", "truncated"});

  // WIDTH x HEIGHT overflowing 64 bits.
  WriteText(dir / "wide.pcd",
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4000000000\nHEIGHT 4000000000\n"
            "DATA binary\n");
  ExpectError([&] { ReadPointCloud(dir / "wide.pcd"); }, {dir / "wide.pcd", "corrupt header"});

  // A PLY vertex with a list property claiming 4e9 entries of 8 bytes.
  std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nproperty list uint double extra\nend_header\n";
  PutBytes(1.0f, false, &ply);
  PutBytes(2.0f, false, &ply);
  PutBytes(3.0f, false, &ply);
  PutBytes(static_cast<uint32_t>(4000000000u), false, &ply);
  ply += std::string(64, '\0');
  WriteBytes(dir / "list.ply", ply);
  EXPECT_EQ(ExitCodeUnderMemoryLimit([&] { ReadPointCloud(dir / "list.ply"); }), 0);
  ExpectError([&] { ReadPointCloud(dir / "list.ply"); }, {dir / "list.ply", "truncated"});

  // LAS 1.4 with a 64-bit point count beyond int64 (converting it to int64 was undefined
  // behaviour: clang's UBSan in the cloud fuzz harness found it; GCC's -fsanitize=undefined does
  // not include float-cast-overflow, and on x86 the conversion gave a negative count, refused).
  const std::vector<std::array<int32_t, 7>> points = {{1, 2, 3, 4, 0, 0, 0}};
  std::string las = LasFile(4, 6, points);
  const uint64_t huge = 0xF000000000000000ull;
  std::memcpy(&las[247], &huge, 8);
  WriteBytes(dir / "huge.las", las);
  ExpectError([&] { ReadPointCloud(dir / "huge.las"); }, {dir / "huge.las", "corrupt LAS header"});
}

TEST(CloudIo, ChunkedReadingMatchesWholeRead) {
  TempDir dir;
  const PointCloud cloud = RandomCloud(10007, 50, true, true);
  PointCloud with_nan = cloud;
  with_nan.positions[5].x() = std::numeric_limits<float>::quiet_NaN();
  for (const std::string name :
       {"c.ply", "c_ascii.ply", "c.pcd", "c_ascii.pcd", "c.bin", "c.xyz"}) {
    SCOPED_TRACE(name);
    const bool ascii = name.find("ascii") != std::string::npos;
    WritePointCloud(dir / name, with_nan, CloudWriteOptions{CloudFormat::kAuto, !ascii});
    const PointCloud whole = ReadPointCloud(dir / name);
    EXPECT_EQ(whole.size(), cloud.size() - 1);
    PointCloud joined;
    int64_t num_chunks = 0;
    const CloudReadStats stats = ForEachPointChunk(dir / name, 1000, [&](const PointCloud& chunk) {
      EXPECT_LE(chunk.size(), 1000u);
      EXPECT_FALSE(chunk.empty());
      joined.Append(chunk);
      ++num_chunks;
    });
    ExpectSameCloud(whole, joined);
    EXPECT_EQ(num_chunks, 11);
    EXPECT_EQ(stats.num_records, 10007);
    EXPECT_EQ(stats.num_non_finite, 1);
  }
  PointCloudReader reader(dir / "c.ply");
  PointCloud chunk;
  ExpectError([&] { reader.ReadChunk(0, &chunk); }, {"chunk size"});
}

}  // namespace
}  // namespace epiloc
