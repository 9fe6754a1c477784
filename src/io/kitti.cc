#include "epiloc/io/kitti.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <random>
#include <regex>
#include <sstream>

#include <Eigen/SparseCholesky>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/core/output_file.h"
#include "epiloc/geo/rigid3.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/io/position_readers.h"
#include "io_internal.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// "key: v1 v2 ..." lines of a KITTI calibration file; keys whose values are not all numbers
// (calib_time) are left out.
class CalibFile {
 public:
  explicit CalibFile(const std::string& path) : path_(path) {
    std::ifstream in(path);
    if (!in) Throw("{}: cannot open calibration file", path);
    std::string line;
    while (ReadLine(in, line, path, 0)) {
      const size_t colon = line.find(':');
      if (colon == std::string::npos) continue;
      std::istringstream values(line.substr(colon + 1));
      std::vector<double> numbers;
      std::string token;
      bool numeric = true;
      while (numeric && values >> token) {
        char* end = nullptr;
        numbers.push_back(std::strtod(token.c_str(), &end));
        numeric = end == token.c_str() + token.size() && std::isfinite(numbers.back());
      }
      if (numeric) values_[Trim(line.substr(0, colon))] = numbers;
    }
  }

  const std::vector<double>& Get(const std::string& key, size_t count) const {
    const auto it = values_.find(key);
    if (it == values_.end()) Throw("{}: missing key '{}'", path_, key);
    if (it->second.size() != count) {
      Throw("{}: '{}' has {} values, expected {}", path_, key, it->second.size(), count);
    }
    return it->second;
  }
  Eigen::Matrix3d Matrix3(const std::string& key) const {
    const auto& v = Get(key, 9);
    return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(v.data());
  }
  Eigen::Vector3d Vector3(const std::string& key) const {
    const auto& v = Get(key, 3);
    return Eigen::Vector3d(v[0], v[1], v[2]);
  }

 private:
  std::string path_;
  std::map<std::string, std::vector<double>> values_;
};

// Files of `dir` with extension `ext`, by frame number (the file name's stem, all digits).
std::map<frame_t, fs::path> NumberedFiles(const fs::path& dir, const std::string& ext) {
  std::map<frame_t, fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file() || entry.path().extension() != ext) continue;
    const std::string stem = entry.path().stem().string();
    if (stem.empty() || stem.size() > 18 ||
        stem.find_first_not_of("0123456789") != std::string::npos) {
      Throw("{}: file name is not a frame number", entry.path().string());
    }
    files[std::stoll(stem)] = entry.path();
  }
  return files;
}

double TimeOfFrame(const std::vector<double>& times, frame_t frame, const std::string& path) {
  if (frame < 0 || frame >= static_cast<frame_t>(times.size())) {
    Throw("{}: no timestamp for frame {} (the file has {} lines)", path, frame, times.size());
  }
  return times[static_cast<size_t>(frame)];
}

// Standard normal deviate by Box-Muller from 53-bit uniforms: the same on every platform.
double Normal(std::mt19937_64& rng) {
  constexpr double kScale = 1.0 / 9007199254740992.0;                   // 2^-53
  const double u1 = (static_cast<double>(rng() >> 11) + 1.0) * kScale;  // (0, 1]
  const double u2 = static_cast<double>(rng() >> 11) * kScale;          // [0, 1)
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// The consumer-GPS error model of kitti.h applied to `truth` (positions only).
PositionTrack SimulateGnss(const PositionTrack& truth, double sigma_m, uint64_t seed) {
  constexpr double kTimeConstantS = 60.0;
  const double bias_fraction = 0.9;
  const double white_fraction = std::sqrt(1.0 - bias_fraction * bias_fraction);
  const Eigen::Vector3d axis_scale(1.0, 1.0, 1.5);
  std::mt19937_64 rng(seed);
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();
  PositionTrack gnss;
  gnss.source = "simulated GNSS";
  for (size_t k = 0; k < truth.samples.size(); ++k) {
    const PositionSample& t = truth.samples[k];
    const double decay =
        k == 0 ? 0.0
               : std::exp(-(t.timestamp_s - truth.samples[k - 1].timestamp_s) / kTimeConstantS);
    Eigen::Vector3d error;
    for (int axis = 0; axis < 3; ++axis) {
      const double sigma_bias = bias_fraction * sigma_m * axis_scale[axis];
      bias[axis] = decay * bias[axis] + sigma_bias * std::sqrt(1.0 - decay * decay) * Normal(rng);
      error[axis] = bias[axis] + white_fraction * sigma_m * axis_scale[axis] * Normal(rng);
    }
    PositionSample sample;
    sample.timestamp_s = t.timestamp_s;
    sample.position = EnuFrame(t.position).ToGeodetic(error);
    gnss.samples.push_back(sample);
  }
  return gnss;
}

std::string DefaultName(const fs::path& raw_dir, int camera) {
  const std::string base = raw_dir.filename().string();
  static const std::regex kPattern(R"((\d{4}_\d{2}_\d{2})_drive_(\d+)(_sync|_extract)?)");
  std::smatch match;
  if (std::regex_match(base, match, kPattern)) {
    return "kitti_" + match[1].str() + "_" + match[2].str() + "_cam" + std::to_string(camera);
  }
  return "kitti_" + base + "_cam" + std::to_string(camera);
}

}  // namespace

void KittiImportOptions::Check() const {
  EPILOC_CHECK(!raw_drive_dir.empty(), "KITTI import: raw_drive_dir is empty");
  EPILOC_CHECK(camera >= 0 && camera <= 3, "KITTI import: camera {} is not in 0..3", camera);
  EPILOC_CHECK(start >= 0, "KITTI import: start {} is negative", start);
  EPILOC_CHECK(stop == -1 || stop > start, "KITTI import: stop {} must be -1 or > start {}", stop,
               start);
  EPILOC_CHECK(step >= 1, "KITTI import: step {} must be >= 1", step);
  // Beyond a kilometre the simulated positions leave the globe's valid range (1e308 wrote empty
  // latitudes and an infinite altitude into gnss.csv, exit 0).
  EPILOC_CHECK(std::isfinite(gps_noise_sigma_m) && gps_noise_sigma_m >= 0 &&
                   gps_noise_sigma_m <= kMaxGpsNoiseSigmaM,
               "KITTI import: gps_noise_sigma_m {} must be in [0, {}] m", gps_noise_sigma_m,
               kMaxGpsNoiseSigmaM);
}

Eigen::Matrix3d EnuFromImu(double roll_rad, double pitch_rad, double yaw_rad) {
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

std::vector<OxtsRecord> ReadKittiOxts(const std::string& oxts_dir) {
  const fs::path data = fs::path(oxts_dir) / "data";
  if (!fs::is_directory(data)) Throw("{}: OXTS data folder not found", data.string());
  const std::string times_path = (fs::path(oxts_dir) / "timestamps.txt").string();
  const std::vector<double> times = ReadTimestamps(times_path);
  std::vector<OxtsRecord> records;
  for (const auto& [frame, path] : NumberedFiles(data, ".txt")) {
    std::ifstream in(path);
    if (!in) Throw("{}: cannot open file", path.string());
    OxtsRecord r;
    r.frame = frame;
    std::string token;
    while (in >> token) r.values.push_back(ParseDouble(token, Where(path.string(), 1)));
    if (r.values.size() != 30) {
      Throw("{}: expected 30 OXTS values, found {}", Where(path.string(), 1), r.values.size());
    }
    r.position = {r.values[0], r.values[1], r.values[2]};
    CheckGeodetic(r.position, Where(path.string(), 1));
    r.roll_rad = r.values[3];
    r.pitch_rad = r.values[4];
    r.yaw_rad = r.values[5];
    r.timestamp_s = TimeOfFrame(times, frame, times_path);
    if (!records.empty() && r.timestamp_s <= records.back().timestamp_s) {
      Throw("{}: timestamp of frame {} is not after that of frame {}", Where(times_path, frame + 1),
            frame, records.back().frame);
    }
    records.push_back(std::move(r));
  }
  if (records.empty()) Throw("{}: no OXTS records", data.string());
  return records;
}

FusedOxts FuseOxtsPositions(const std::vector<OxtsRecord>& records) {
  // dataformat.txt: vn 6, ve 7, vu 10, pos_accuracy 23, vel_accuracy 24.
  constexpr int kVn = 6, kVe = 7, kVu = 10, kPosAccuracy = 23, kVelAccuracy = 24;
  // Floors: an accuracy reported below these is not believed (1 cm: an RTK fix; 5 mm/s).
  constexpr double kMinPositionSigmaM = 0.01, kMinVelocitySigmaMps = 0.005;
  FusedOxts out;
  for (const OxtsRecord& r : records) out.positions.push_back(r.position);
  const int n = static_cast<int>(records.size());
  if (n < 2) {
    out.why_not = "fewer than two records";
    return out;
  }
  for (const OxtsRecord& r : records) {
    const double a = r.values[kPosAccuracy], b = r.values[kVelAccuracy];
    if (!(std::isfinite(a) && a > 0 && std::isfinite(b) && b > 0)) {
      out.why_not = fmt::format("record {} reports no position and velocity accuracy", r.frame);
      return out;
    }
    // A road vehicle's unit: a velocity beyond 1000 m/s is a broken record, not a fast car.
    for (const int k : {kVn, kVe, kVu}) {
      if (!(std::abs(r.values[k]) <= 1000.0)) {
        out.why_not = fmt::format("record {} has velocity {}", r.frame, r.values[k]);
        return out;
      }
    }
  }
  // Unknowns per axis: positions p_0..p_(n-1), then velocity errors e_0..e_(n-1). Every row is a
  // weighted residual; the normal equations are assembled from them. The same matrix serves the
  // three axes (the weights do not depend on the axis).
  const EnuFrame enu(records.front().position);
  Eigen::MatrixXd recorded(n, 3), rhs = Eigen::MatrixXd::Zero(2 * n, 3);
  std::vector<Eigen::Triplet<double>> entries;
  // Adds the residual sum_k c_k x_(j_k) - y, weight 1/sigma^2, to the normal equations.
  const auto add = [&](const std::vector<std::pair<int, double>>& terms, const Eigen::RowVector3d& y,
                       double sigma) {
    const double w = 1.0 / (sigma * sigma);
    for (const auto& [j, cj] : terms) {
      for (const auto& [k, ck] : terms) entries.emplace_back(j, k, w * cj * ck);
      rhs.row(j) += w * cj * y;
    }
  };
  const auto velocity_sigma = [&](int i) {
    return std::max(records[i].values[kVelAccuracy], kMinVelocitySigmaMps);
  };
  for (int i = 0; i < n; ++i) {
    recorded.row(i) = enu.ToEnu(records[i].position).transpose();
    add({{i, 1.0}}, recorded.row(i), std::max(records[i].values[kPosAccuracy], kMinPositionSigmaM));
  }
  const auto velocity = [&](int i) {
    const OxtsRecord& r = records[i];
    return Eigen::Vector3d(enu.EnuFromLocalEnu(r.position) *
                           Eigen::Vector3d(r.values[kVe], r.values[kVn], r.values[kVu]));
  };
  // The velocity's error e_i is slow (a GNSS/INS solution drifts over seconds, it does not jump
  // between samples): a first-order Gauss-Markov process with the reported accuracy as its
  // steady-state sigma and time constant kVelocityErrorTimeS; what it leaves of a step is
  // measured to kMinVelocitySigmaMps. Over a few samples the steps follow the velocity; over
  // tens of seconds the positions set the shape.
  constexpr double kVelocityErrorTimeS = 10.0;
  add({{n, 1.0}}, Eigen::RowVector3d::Zero(), velocity_sigma(0));
  for (int i = 0; i + 1 < n; ++i) {
    const double dt = records[i + 1].timestamp_s - records[i].timestamp_s;
    const Eigen::RowVector3d step = (0.5 * (velocity(i) + velocity(i + 1)) * dt).transpose();
    // p_(i+1) - p_i - (v_i + e_i) dt = 0
    add({{i + 1, 1.0}, {i, -1.0}, {n + i, -dt}}, step, kMinVelocitySigmaMps * dt);
    // e_(i+1) - phi e_i = 0, sigma_e sqrt(1 - phi^2)
    const double phi = std::exp(-dt / kVelocityErrorTimeS);
    add({{n + i + 1, 1.0}, {n + i, -phi}}, Eigen::RowVector3d::Zero(),
        std::max(velocity_sigma(i + 1) * std::sqrt(1.0 - phi * phi), 1e-6));
  }
  Eigen::SparseMatrix<double> normal(2 * n, 2 * n);
  normal.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  if (solver.info() != Eigen::Success) {
    out.why_not = "the least-squares system could not be solved";
    return out;
  }
  const Eigen::MatrixXd fused = solver.solve(rhs);
  if (!fused.allFinite()) {
    out.why_not = "the least-squares solution is not finite";
    return out;
  }
  for (int i = 0; i < n; ++i) {
    const Geodetic position = enu.ToGeodetic(fused.row(i).transpose());
    if (!IsValidGeodetic(position)) {
      out.why_not = fmt::format("record {} would move out of range", records[i].frame);
      out.max_correction_m = 0.0;
      for (int j = 0; j < n; ++j) out.positions[j] = records[j].position;
      return out;
    }
    out.positions[i] = position;
    out.max_correction_m =
        std::max(out.max_correction_m, (fused.row(i) - recorded.row(i)).head<2>().norm());
  }
  out.fused = true;
  return out;
}

Drive ImportKitti(const KittiImportOptions& options) {
  options.Check();
  fs::path raw = fs::absolute(options.raw_drive_dir).lexically_normal();
  if (raw.filename().empty()) raw = raw.parent_path();
  if (!fs::is_directory(raw)) Throw("{}: KITTI drive folder not found", raw.string());
  const fs::path calib_dir = raw.parent_path();
  // The drive folder and the calibration folder above it are inputs (often read-only shared data):
  // the import once wrote into them.
  if (!options.out_dir.empty()) {
    for (const fs::path& input : {raw, calib_dir}) {
      // A drive folder right under "/" has no calibration folder to protect.
      if (input == input.root_path()) continue;
      if (IsWithinFolder(options.out_dir, input.string())) {
        Throw(
            "KITTI import: the output folder {} is inside the KITTI input folder {}: refusing to "
            "write into an input",
            options.out_dir, input.string());
      }
    }
  }
  const std::string n = "0" + std::to_string(options.camera);

  const CalibFile cam_to_cam((calib_dir / "calib_cam_to_cam.txt").string());
  const CalibFile velo_to_cam((calib_dir / "calib_velo_to_cam.txt").string());
  const CalibFile imu_to_velo((calib_dir / "calib_imu_to_velo.txt").string());
  const auto& p = cam_to_cam.Get("P_rect_" + n, 12);
  const auto& size = cam_to_cam.Get("S_rect_" + n, 2);
  const Eigen::Matrix3d rect0_from_cam0 = cam_to_cam.Matrix3("R_rect_00");

  Drive drive;
  drive.name = options.name.empty() ? DefaultName(raw, options.camera) : options.name;
  drive.colour = options.camera >= 2;
  drive.camera.width = static_cast<int>(std::lround(size[0]));
  drive.camera.height = static_cast<int>(std::lround(size[1]));
  drive.camera.fx = p[0];
  drive.camera.cx = p[2];
  drive.camera.fy = p[5];
  drive.camera.cy = p[6];
  drive.camera.Check((calib_dir / "calib_cam_to_cam.txt").string() + ": P_rect_" + n);

  // Camera N's centre in rectified cam0 coordinates: P = K [I | t], centre = -t.
  const Eigen::Vector3d center_in_rect0 =
      -drive.camera.K().inverse() * Eigen::Vector3d(p[3], p[7], p[11]);
  const Rigid3d velo_from_imu =
      Rigid3d::FromMatrix(imu_to_velo.Matrix3("R"), imu_to_velo.Vector3("T"));
  const Rigid3d cam0_from_velo =
      Rigid3d::FromMatrix(velo_to_cam.Matrix3("R"), velo_to_cam.Vector3("T"));
  const Rigid3d rect0_from_imu = Rigid3d::FromMatrix(rect0_from_cam0, Eigen::Vector3d::Zero()) *
                                 cam0_from_velo * velo_from_imu;
  const Rigid3d imu_from_rect0 = rect0_from_imu.Inverse();
  const Rigid3d imu_from_velo = velo_from_imu.Inverse();
  const Eigen::Vector3d center_in_imu = imu_from_rect0 * center_in_rect0;

  // Frames.
  const fs::path image_dir = raw / ("image_" + n);
  if (!fs::is_directory(image_dir / "data")) {
    Throw("{}: images of camera {} not found", (image_dir / "data").string(), options.camera);
  }
  const std::string image_times_path = (image_dir / "timestamps.txt").string();
  const std::vector<double> image_times = ReadTimestamps(image_times_path);
  const auto in_span = [&](frame_t f) {
    return f >= options.start && (options.stop < 0 || f < options.stop);
  };
  const fs::path velo_dir = raw / "velodyne_points";
  const std::string velo_times_path = (velo_dir / "timestamps.txt").string();
  std::vector<double> trigger_times;
  using FrameTime = KittiImportOptions::FrameTime;
  const bool has_trigger_times = fs::is_regular_file(velo_times_path);
  const bool at_trigger = options.frame_time == FrameTime::kTrigger ||
                          (options.frame_time == FrameTime::kAuto && has_trigger_times);
  if (options.frame_time == FrameTime::kAuto) {
    if (has_trigger_times) {
      spdlog::info("{}: frames at the Velodyne's trigger times, the truth interpolated there",
                   velo_times_path);
    } else {
      spdlog::warn(
          "{}: not found: frames at their image timestamps, the truth at the OXTS "
          "records (some tens of milliseconds after the camera's exposure)",
          velo_times_path);
    }
  }
  if (at_trigger) {
    if (!has_trigger_times) {
      Throw("{}: not found: the frames' trigger times (--frame-time trigger) are the Velodyne's",
            velo_times_path);
    }
    trigger_times = ReadTimestamps(velo_times_path);
  }
  for (const auto& [frame, path] : NumberedFiles(image_dir / "data", ".png")) {
    if (!in_span(frame) || (frame - options.start) % options.step != 0) continue;
    const double t = at_trigger ? TimeOfFrame(trigger_times, frame, velo_times_path)
                                : TimeOfFrame(image_times, frame, image_times_path);
    drive.frames.push_back({frame, t, path.string()});
  }
  if (drive.frames.empty()) {
    Throw("{}: no frames in the selection [{}, {}) step {}", (image_dir / "data").string(),
          options.start, options.stop, options.step);
  }
  FrameReader(drive).ReadGrey(0);  // the images must have the rectified size

  // Ground truth: the camera track at the OXTS samples of the span.
  std::vector<OxtsRecord> oxts = ReadKittiOxts((raw / "oxts").string());
  if (options.oxts_positions == KittiImportOptions::OxtsPositions::kFused) {
    const FusedOxts fused = FuseOxtsPositions(oxts);
    if (fused.fused) {
      for (size_t i = 0; i < oxts.size(); ++i) oxts[i].position = fused.positions[i];
      spdlog::info("{}: OXTS positions fused with the unit's velocity (moved by at most {:.2f} m)",
                   (raw / "oxts").string(), fused.max_correction_m);
    } else {
      spdlog::warn("{}: OXTS positions imported as recorded: {}", (raw / "oxts").string(),
                   fused.why_not);
    }
  }
  PositionTrack imu_track;  // orientation field holds enu_from_imu
  PositionTrack truth;
  truth.source = (raw / "oxts").string();
  PositionTrack camera_track;  // the camera at every OXTS record, for kTrigger
  for (const auto& r : oxts) {
    const Eigen::Matrix3d enu_from_imu = EnuFromImu(r.roll_rad, r.pitch_rad, r.yaw_rad);
    PositionSample imu;
    imu.timestamp_s = r.timestamp_s;
    imu.position = r.position;
    imu.enu_from_cam = Eigen::Quaterniond(enu_from_imu);
    imu.frame = r.frame;
    imu_track.samples.push_back(imu);
    PositionSample cam;
    cam.timestamp_s = r.timestamp_s;
    cam.position = EnuFrame(r.position).ToGeodetic(enu_from_imu * center_in_imu);
    cam.enu_from_cam =
        (EnuToEnuRotation(cam.position, r.position) * *imu.enu_from_cam * imu_from_rect0.rotation)
            .normalized();
    cam.frame = r.frame;
    camera_track.samples.push_back(cam);
    if (in_span(r.frame) && !at_trigger) truth.samples.push_back(cam);
  }
  if (at_trigger) {
    // One row per OXTS record of the span, at its frame's trigger time (the OXTS runs at 10 Hz
    // here: the neighbouring records are 0.1 s apart; the drive's first trigger precedes its first
    // record by a few tens of milliseconds and is extrapolated from the first two).
    constexpr double kMaxGapS = 0.2;
    for (const auto& r : oxts) {
      if (!in_span(r.frame)) continue;
      const double t = TimeOfFrame(trigger_times, r.frame, velo_times_path);
      std::optional<PositionSample> cam = camera_track.Interpolate(t, kMaxGapS);
      if (!cam) {
        Throw("{}: no OXTS record within {} s of frame {}'s trigger time", truth.source, kMaxGapS,
              r.frame);
      }
      cam->frame = r.frame;
      truth.samples.push_back(*cam);
    }
  }
  if (truth.samples.empty()) Throw("{}: no OXTS record in the selected span", truth.source);
  if (options.gps_noise_sigma_m > 0) {
    drive.gnss = SimulateGnss(truth, options.gps_noise_sigma_m, options.seed);
  } else {
    drive.gnss.source = truth.source;
    for (const auto& s : truth.samples) {
      PositionSample g;
      g.timestamp_s = s.timestamp_s;
      g.position = s.position;
      drive.gnss.samples.push_back(g);
    }
  }
  drive.ground_truth = truth;

  // LiDAR scans present in the span, posed by the IMU track at the scan time.
  if (fs::is_directory(velo_dir / "data")) {
    const std::vector<double> velo_times = ReadTimestamps(velo_times_path);
    for (const auto& [frame, path] : NumberedFiles(velo_dir / "data", ".bin")) {
      if (!in_span(frame)) continue;
      LidarScan scan;
      scan.scan = frame;
      scan.timestamp_s = TimeOfFrame(velo_times, frame, velo_times_path);
      scan.path = path.string();
      scan.format = "kitti_bin";
      const auto imu = imu_track.Interpolate(scan.timestamp_s, 1.0);
      if (!imu) {
        Throw("{}: no OXTS pose within 1 s of scan {}", Where(velo_times_path, frame + 1), frame);
      }
      scan.sensor_position =
          EnuFrame(imu->position).ToGeodetic(*imu->enu_from_cam * imu_from_velo.translation);
      scan.enu_from_sensor = (EnuToEnuRotation(scan.sensor_position, imu->position) *
                              *imu->enu_from_cam * imu_from_velo.rotation)
                                 .normalized();
      drive.lidar.push_back(scan);
    }
  }

  spdlog::info("{}: {} frames, {} positions, {} LiDAR scans", drive.name, drive.frames.size(),
               truth.samples.size(), drive.lidar.size());
  if (!options.out_dir.empty()) {
    drive.dir = options.out_dir;
    WriteDrive(drive, options.out_dir);
  }
  return drive;
}

}  // namespace epiloc
