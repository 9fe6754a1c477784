// A minimal PLY writer and reader for the synthetic LiDAR map (binary little endian; x y z
// intensity as float32, red green blue as uint8). A general point-cloud module will replace it.
#include <cstring>
#include <fstream>
#include <sstream>

#include "epiloc/core/error.h"
#include "epiloc/synth/lidar.h"

namespace epiloc {
namespace {

constexpr size_t kRecordBytes = 4 * sizeof(float) + 3;
const char* const kProperties[] = {
    "property float x",   "property float y",     "property float z",   "property float intensity",
    "property uchar red", "property uchar green", "property uchar blue"};

bool LittleEndianHost() {
  const uint16_t one = 1;
  uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

void PutFloat(float value, char* out) {
  std::memcpy(out, &value, 4);
  if (!LittleEndianHost()) std::swap(out[0], out[3]), std::swap(out[1], out[2]);
}

float GetFloat(const char* in) {
  char bytes[4] = {in[0], in[1], in[2], in[3]};
  if (!LittleEndianHost()) std::swap(bytes[0], bytes[3]), std::swap(bytes[1], bytes[2]);
  float value;
  std::memcpy(&value, bytes, 4);
  return value;
}

}  // namespace

void WritePly(const std::string& path,
              const std::vector<LidarPoint>& points,
              const Rigid3d& frame_from_world) {
  std::ofstream out(path, std::ios::binary);
  if (!out) Throw("{}: cannot open for writing", path);
  out << "ply\nformat binary_little_endian 1.0\ncomment epiloc synthetic LiDAR\n"
      << "element vertex " << points.size() << "\n";
  for (const char* property : kProperties) out << property << "\n";
  out << "end_header\n";
  const Eigen::Matrix3d r = frame_from_world.rotation.toRotationMatrix();
  std::vector<char> buffer(kRecordBytes * std::min<size_t>(points.size(), 65536));
  for (size_t begin = 0; begin < points.size(); begin += 65536) {
    const size_t end = std::min(points.size(), begin + 65536);
    char* p = buffer.data();
    for (size_t i = begin; i < end; ++i, p += kRecordBytes) {
      const Eigen::Vector3d x =
          r * points[i].position.cast<double>() + frame_from_world.translation;
      PutFloat(static_cast<float>(x.x()), p);
      PutFloat(static_cast<float>(x.y()), p + 4);
      PutFloat(static_cast<float>(x.z()), p + 8);
      PutFloat(points[i].intensity, p + 12);
      std::memcpy(p + 16, points[i].rgb.data(), 3);
    }
    out.write(buffer.data(), static_cast<std::streamsize>((end - begin) * kRecordBytes));
  }
  out.close();
  if (!out) Throw("{}: write failed", path);
}

std::vector<LidarPoint> ReadPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Throw("{}: cannot open", path);
  std::string line;
  std::vector<std::string> header;
  int64_t count = -1;
  while (std::getline(in, line)) {
    if (line.rfind("comment", 0) == 0) continue;
    if (line == "end_header") break;
    if (line.rfind("element vertex ", 0) == 0) {
      count = std::stoll(line.substr(15));
      continue;
    }
    header.push_back(line);
  }
  const std::vector<std::string> expected = {"ply", "format binary_little_endian 1.0"};
  bool ok = header.size() == 2 + std::size(kProperties) && count >= 0;
  for (size_t i = 0; ok && i < header.size(); ++i) {
    ok = header[i] == (i < 2 ? expected[i] : std::string(kProperties[i - 2]));
  }
  if (!ok)
    Throw("{}: not a PLY in the layout of epiloc's synthetic LiDAR (x y z intensity rgb)", path);
  std::vector<char> data(static_cast<size_t>(count) * kRecordBytes);
  in.read(data.data(), static_cast<std::streamsize>(data.size()));
  if (in.gcount() != static_cast<std::streamsize>(data.size())) {
    Throw("{}: truncated, expected {} points", path, count);
  }
  std::vector<LidarPoint> points(count);
  for (int64_t i = 0; i < count; ++i) {
    const char* p = data.data() + i * kRecordBytes;
    points[i].position = Eigen::Vector3f(GetFloat(p), GetFloat(p + 4), GetFloat(p + 8));
    points[i].intensity = GetFloat(p + 12);
    std::memcpy(points[i].rgb.data(), p + 16, 3);
  }
  return points;
}

}  // namespace epiloc
