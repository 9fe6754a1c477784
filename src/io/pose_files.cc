#include "epiloc/io/pose_files.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <Eigen/SVD>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
#include "epiloc/io/position_readers.h"

namespace epiloc {
namespace {

// Calls f(numbers, line_number, where) for each line that is neither blank nor a '#' comment;
// each must hold `count` finite whitespace-separated numbers.
template <typename F>
void ForEachNumericLine(const std::string& path, size_t count, const std::string& what, F&& f) {
  std::ifstream in(path);
  if (!in) Throw("{}: cannot open trajectory file", path);
  std::string line;
  int64_t line_number = 0;
  std::vector<double> numbers;
  while (ReadLine(in, line, path, line_number + 1)) {
    ++line_number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    const std::string where = Where(path, line_number);
    numbers.clear();
    std::istringstream tokens(trimmed);
    std::string token;
    bool all_numbers = true;
    while (tokens >> token) {
      char* end = nullptr;
      const double value = std::strtod(token.c_str(), &end);
      if (end != token.c_str() + token.size()) {
        all_numbers = false;
        break;
      }
      numbers.push_back(value);
    }
    if (!all_numbers || numbers.size() != count) {
      Throw("{}: expected {} numbers ({}), got '{}'", where, count, what, trimmed);
    }
    for (const double v : numbers) {
      if (!std::isfinite(v)) Throw("{}: non-finite number in '{}'", where, trimmed);
    }
    f(numbers, line_number, where);
  }
}

}  // namespace

std::vector<StampedPose> ReadTumPoses(const std::string& path) {
  std::vector<StampedPose> poses;
  ForEachNumericLine(path, 8, "t x y z qx qy qz qw",
                     [&](const std::vector<double>& v, int64_t line, const std::string& where) {
                       StampedPose pose;
                       pose.timestamp_s = v[0];
                       pose.line = line;
                       const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
                       if (std::abs(q.norm() - 1.0) > 1e-3) {
                         Throw("{}: quaternion (qx qy qz qw) = ({} {} {} {}) is not of unit length",
                               where, v[4], v[5], v[6], v[7]);
                       }
                       pose.world_from_cam = Rigid3d(q.normalized(), {v[1], v[2], v[3]});
                       if (!poses.empty() && pose.timestamp_s <= poses.back().timestamp_s) {
                         Throw("{}: timestamp {} is not after the previous one ({})", where,
                               FormatDouble(pose.timestamp_s),
                               FormatDouble(poses.back().timestamp_s));
                       }
                       poses.push_back(pose);
                     });
  return poses;
}

std::vector<StampedPose> ReadKittiPoses(const std::string& path,
                                        const std::string& times_path,
                                        bool check_rotation) {
  std::vector<double> times;
  if (!times_path.empty()) times = ReadTimestamps(times_path);
  std::vector<StampedPose> poses;
  ForEachNumericLine(path, 12, "row-major 3x4 pose",
                     [&](const std::vector<double>& v, int64_t line, const std::string& where) {
                       StampedPose pose;
                       pose.frame = static_cast<frame_t>(poses.size());
                       pose.line = line;
                       if (times.empty()) {
                         pose.timestamp_s = static_cast<double>(pose.frame);
                       } else if (pose.frame < static_cast<frame_t>(times.size())) {
                         pose.timestamp_s = times[static_cast<size_t>(pose.frame)];
                       } else {
                         Throw("{}: no timestamp for pose {} in {} ({} lines)", where, pose.frame,
                               times_path, times.size());
                       }
                       Eigen::Matrix3d r;
                       r << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
                       const Eigen::Vector3d t(v[3], v[7], v[11]);
                       if (check_rotation) {
                         if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-3 ||
                             r.determinant() < 0.0) {
                           Throw("{}: the 3x3 part is not a rotation matrix", where);
                         }
                         const Eigen::JacobiSVD<Eigen::Matrix3d> svd(
                             r, Eigen::ComputeFullU | Eigen::ComputeFullV);
                         r = svd.matrixU() * svd.matrixV().transpose();
                         pose.world_from_cam = Rigid3d::FromMatrix(r, t);
                       } else {
                         pose.world_from_cam.translation = t;
                       }
                       poses.push_back(pose);
                     });
  return poses;
}

void WriteTumPoses(const std::vector<StampedPose>& poses,
                   const std::string& path,
                   const std::vector<std::string>& comments) {
  AtomicOfstream file(path);
  std::ofstream& out = file.stream();
  for (const std::string& comment : comments) out << "# " << comment << '\n';
  for (const StampedPose& pose : poses) {
    const Eigen::Quaterniond& q = pose.world_from_cam.rotation;
    const Eigen::Vector3d& t = pose.world_from_cam.translation;
    out << fmt::format("{} {} {} {} {:.9f} {:.9f} {:.9f} {:.9f}\n", FormatDouble(pose.timestamp_s),
                       FormatDouble(t.x()), FormatDouble(t.y()), FormatDouble(t.z()), q.x(), q.y(),
                       q.z(), q.w());
  }
  file.Commit();
}

}  // namespace epiloc
