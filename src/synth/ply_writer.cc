// The synthetic LiDAR map's PLY files, through the cloud module's reader and writer.
#include "epiloc/cloud/cloud_io.h"
#include "epiloc/core/error.h"
#include "epiloc/synth/lidar.h"

namespace epiloc {

void WritePly(const std::string& path,
              const std::vector<LidarPoint>& points,
              const Rigid3d& frame_from_world) {
  const Eigen::Matrix3d r = frame_from_world.rotation.toRotationMatrix();
  PointCloud cloud;
  cloud.Reserve(points.size(), true, true);
  for (const LidarPoint& point : points) {
    const Eigen::Vector3d x = r * point.position.cast<double>() + frame_from_world.translation;
    cloud.positions.push_back(x.cast<float>());
    cloud.intensity.push_back(point.intensity);
    cloud.rgb.push_back(point.rgb);
  }
  WritePointCloud(path, cloud, CloudWriteOptions{CloudFormat::kPly, true});
}

std::vector<LidarPoint> ReadPly(const std::string& path) {
  const PointCloud cloud = ReadPointCloud(path, CloudReadOptions{CloudFormat::kPly});
  EPILOC_CHECK(cloud.HasIntensity() && cloud.HasColour(),
               "{}: not a PLY in the layout of epiloc's synthetic LiDAR (x y z intensity rgb)",
               path);
  std::vector<LidarPoint> points(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    points[i].position = cloud.positions[i];
    points[i].intensity = cloud.intensity[i];
    points[i].rgb = cloud.rgb[i];
  }
  return points;
}

}  // namespace epiloc
