#include "epiloc/synth/drive_gen.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/csv.h"
#include "epiloc/core/error.h"
#include "epiloc/io/drive.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

// Runs fn(i) for i in [0, n) on `num_threads` threads; rethrows the first exception.
void ParallelFor(int n, int num_threads, const std::function<void(int)>& fn) {
  std::atomic<int> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex mutex;
  const auto work = [&] {
    for (int i = next++; i < n && !failed; i = next++) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < num_threads; ++t) threads.emplace_back(work);
  work();
  for (std::thread& t : threads) t.join();
  if (error) std::rethrow_exception(error);
}

std::string FrameImage(int frame, const DriveOptions& drive) {
  return fmt::format("images/{:06d}.{}", frame, drive.jpeg_quality > 0 ? "jpg" : "png");
}

bool SamePose(const Rigid3d& a, const Rigid3d& b) {
  return a.rotation.coeffs() == b.rotation.coeffs() && a.translation == b.translation;
}

// One drive being generated.
struct DriveJob {
  const DriveOptions* options = nullptr;
  fs::path dir;
  DrivePath path;
  std::vector<double> times;
  Renderer renderer;
  uint64_t seed = 0;
  DriveScene scene;  // world, sun and moving cars of this drive
};

}  // namespace

void SynthOptions::Check() const {
  EPILOC_CHECK(std::isfinite(length_m) && length_m >= 30,
               "synth options: length_m = {} must be at least 30 m", length_m);
  // Bounds that keep a typo from taking all memory and days (--length-m 1e9 ran without end,
  // --query-speed-mps 1e-9 took 6.8 GB within a minute).
  constexpr double kMaxLengthM = 5000;
  constexpr double kMaxFramesPerDrive = 200000;
  EPILOC_CHECK(length_m <= kMaxLengthM, "synth options: length_m = {} must be at most {} m",
               length_m, kMaxLengthM);
  for (const DriveOptions* drive : {&survey, &query}) {
    double min_speed_mps = drive->speed_mps;
    for (const SpeedSection& s : drive->sections) min_speed_mps = std::min(min_speed_mps, s.speed_mps);
    double stopped_s = std::max(drive->end_stop_s, 0.0);
    for (const StopEvent& s : drive->stops) stopped_s += std::max(s.duration_s, 0.0);
    if (!(min_speed_mps > 0) || !(drive->frame_rate_hz > 0)) continue;  // DriveOptions::Check
    const double frames = (length_m / min_speed_mps + stopped_s) * drive->frame_rate_hz;
    EPILOC_CHECK(frames <= kMaxFramesPerDrive,
                 "synth options: {}: about {:.3g} frames ({} m at {} m/s, {} Hz); at most {:.0f} "
                 "are generated per drive",
                 drive->name, frames, length_m, min_speed_mps, drive->frame_rate_hz,
                 kMaxFramesPerDrive);
  }
  ResolvedWorldOptions().Check();
  appearance.Check();
  survey.Check("synth options: survey");
  query.Check("synth options: query");
  EPILOC_CHECK(query.start_offset_m + query.end_offset_m < length_m - 1,
               "synth options: the query's offsets leave nothing to drive");
  for (const DriveOptions* drive : {&survey, &query}) {
    // A drive stays on the built street and keeps 40 m of it ahead of its last frame.
    EPILOC_CHECK(drive->start_offset_m >= -world.margin_before_m,
                 "synth options: {}: start_offset_m = {} reaches before the built street ({} m)",
                 drive->name, drive->start_offset_m, -world.margin_before_m);
    EPILOC_CHECK(drive->end_offset_m >= 40.0 - world.margin_after_m,
                 "synth options: {}: end_offset_m = {} must be >= {} m (40 m of built street "
                 "ahead of the last frame)",
                 drive->name, drive->end_offset_m, 40.0 - world.margin_after_m);
    EPILOC_CHECK(!drive->turn_in || world.side_street.enabled,
                 "synth options: {}: turn_in needs world.side_street.enabled", drive->name);
  }
  lidar_options.Check();
  EPILOC_CHECK(num_threads >= 1, "synth options: num_threads must be >= 1");
  EPILOC_CHECK(png_compression >= 0 && png_compression <= 9,
               "synth options: png_compression must be in [0, 9]");
}

WorldOptions SynthOptions::ResolvedWorldOptions() const {
  WorldOptions w = world;
  w.length_m = length_m;
  w.seed = seed;
  w.num_threads = num_threads;
  return w;
}

SynthSummary GenerateSynthetic(const SynthOptions& options,
                               const std::string& out_dir,
                               const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  options.Check();
  const auto survey_world =
      std::make_shared<const World>(BuildWorld(options.ResolvedWorldOptions()));
  const World& world = *survey_world;
  const EnuFrame world_frame(world.origin());
  const fs::path out(out_dir);
  std::error_code ec;
  for (const std::string sub : {"survey/images", "query/images", "lidar"}) {
    if (sub == "survey/images" && !options.survey_frames) continue;
    fs::create_directories(out / sub, ec);
    if (ec) Throw("{}: cannot create directory: {}", (out / sub).string(), ec.message());
  }

  std::vector<DriveJob> drives;
  drives.reserve(2);
  int index = 0;
  for (const DriveOptions* o : {&options.survey, &options.query}) {
    const uint64_t seed = MixSeed(options.seed, 100 + index);
    DrivePath path(world, *o, options.length_m, seed);
    std::vector<double> times = path.FrameTimes();
    drives.push_back({o, out / (index == 0 ? "survey" : "query"), std::move(path), std::move(times),
                      Renderer(o->camera, o->render), seed, DriveScene()});
    ++index;
  }
  std::array<DriveScene, 2> scenes = MakeDriveScenes(options.appearance, survey_world,
                                                     drives[0].path, drives[1].path, options.seed);
  for (int d = 0; d < 2; ++d) drives[d].scene = scenes[d];
  const DrivePath& survey_path = drives[0].path;
  std::vector<Rigid3d> sensor_poses;
  std::vector<double> scan_times;
  if (options.lidar) {
    for (double s = survey_path.start_s_m(); s <= survey_path.end_s_m() + 1e-9;
         s += options.lidar_options.scan_spacing_m) {
      sensor_poses.push_back(
          survey_path.WorldFromSensorAtS(s, options.lidar_options.sensor_height_m));
      scan_times.push_back(survey_path.TimeAtS(s));
    }
  }

  // Frames of both drives, in parallel.
  std::vector<std::pair<int, int>> tasks;
  const int first_drive = options.survey_frames ? 0 : 1;
  for (int d = first_drive; d < 2; ++d) {
    for (int f = 0; f < static_cast<int>(drives[d].times.size()); ++f) tasks.emplace_back(d, f);
  }
  const int64_t total = static_cast<int64_t>(tasks.size() + sensor_poses.size());
  std::mutex progress_mutex;
  int64_t done = 0;
  const auto report = [&](int64_t n) {
    std::lock_guard<std::mutex> lock(progress_mutex);
    done += n;
    if (progress) progress(done, total);
  };
  // Run-length matching suits clean rendered frames; noisy ones compress as well, and faster,
  // with Huffman coding alone.
  const auto png_params = [&](const DriveOptions& drive) {
    return std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, options.png_compression,
                            cv::IMWRITE_PNG_STRATEGY,
                            drive.render.noise_sigma > 0 ? cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY
                                                         : cv::IMWRITE_PNG_STRATEGY_RLE};
  };
  const auto image_params = [&](const DriveOptions& drive) {
    if (drive.jpeg_quality > 0)
      return std::vector<int>{cv::IMWRITE_JPEG_QUALITY, drive.jpeg_quality};
    return png_params(drive);
  };
  // A still vehicle's frames repeat the first frame of its stand (same pose, same image).
  std::vector<std::vector<int>> source(2);
  for (int d = 0; d < 2; ++d) {
    const DriveJob& job = drives[d];
    const double exposure = job.options->exposure_s;
    for (int f = 0; f < static_cast<int>(job.times.size()); ++f) {
      const double t = job.times[f];
      const bool repeat =
          job.options->still_when_stopped && f > 0 &&
          SamePose(job.path.CamFromWorld(t), job.path.CamFromWorld(job.times[f - 1])) &&
          SamePose(job.path.CamFromWorld(t + 0.5 * exposure),
                   job.path.CamFromWorld(job.times[f - 1] + 0.5 * exposure));
      source[d].push_back(repeat ? source[d][f - 1] : f);
    }
  }
  std::vector<std::pair<int, int>> unique_tasks;
  for (const auto& [d, f] : tasks) {
    if (source[d][f] == f) unique_tasks.emplace_back(d, f);
  }
  ParallelFor(static_cast<int>(unique_tasks.size()), options.num_threads, [&](int i) {
    const DriveJob& job = drives[unique_tasks[i].first];
    const int frame = unique_tasks[i].second;
    const double t = job.times[frame];
    std::optional<Rigid3d> exposure_end;
    if (job.options->exposure_s > 0)
      exposure_end = job.path.CamFromWorld(t + 0.5 * job.options->exposure_s);
    const RenderResult result = job.scene.Render(job.renderer, t, job.path.CamFromWorld(t),
                                                 exposure_end, MixSeed(job.seed, 1000000 + frame));
    cv::Mat image = result.image;
    if (job.options->grey) cv::cvtColor(result.image, image, cv::COLOR_BGR2GRAY);
    const std::string file = (job.dir / FrameImage(frame, *job.options)).string();
    if (!cv::imwrite(file, image, image_params(*job.options))) {
      Throw("{}: cannot write image", file);
    }
    report(1);
  });
  for (const auto& [d, f] : tasks) {
    if (source[d][f] == f) continue;
    const DriveOptions& drive = *drives[d].options;
    fs::copy_file(drives[d].dir / FrameImage(source[d][f], drive),
                  drives[d].dir / FrameImage(f, drive), fs::copy_options::overwrite_existing, ec);
    if (ec)
      Throw("{}: cannot write image: {}", (drives[d].dir / FrameImage(f, drive)).string(),
            ec.message());
    report(1);
  }

  // LiDAR map and scan list.
  std::vector<LidarPoint> points;
  std::vector<LidarScan> scan_entries;
  if (options.lidar) {
    LidarOptions lidar = options.lidar_options;
    lidar.num_threads = options.num_threads;
    int64_t scans_reported = 0;
    points = SimulateScans(world, sensor_poses, lidar, MixSeed(options.seed, 200),
                           [&](int64_t scans_done, int64_t) {
                             report(scans_done - scans_reported);
                             scans_reported = scans_done;
                           });
    WritePly((out / "lidar" / "map.ply").string(), points);
    CsvWriter csv((out / "lidar" / "scans.csv").string(),
                  {"scan", "timestamp_s", "lat_deg", "lon_deg", "alt_m", "x_m", "y_m", "z_m", "qw",
                   "qx", "qy", "qz"});
    std::vector<std::vector<LidarPoint>> per_scan(options.lidar_scan_files ? sensor_poses.size()
                                                                           : 0);
    if (options.lidar_scan_files) {
      for (const LidarPoint& p : points) per_scan[p.scan].push_back(p);
      fs::create_directories(out / "survey" / "lidar", ec);
      if (ec)
        Throw("{}: cannot create directory: {}", (out / "survey" / "lidar").string(), ec.message());
    }
    for (size_t i = 0; i < sensor_poses.size(); ++i) {
      const Eigen::Vector3d x = sensor_poses[i].translation;
      LidarScan scan;
      scan.scan = static_cast<int64_t>(i);
      scan.timestamp_s = scan_times[i];
      scan.sensor_position = world_frame.ToGeodetic(x);
      scan.enu_from_sensor =
          Eigen::Quaterniond(LocalEnuFromWorldEnu(world_frame, scan.sensor_position) *
                             sensor_poses[i].rotation.toRotationMatrix())
              .normalized();
      scan.format = "ply";
      scan.path = fmt::format("lidar/{:06d}.ply", i);
      const Eigen::Quaterniond& q = scan.enu_from_sensor;
      csv.WriteRow({std::to_string(i), FormatDouble(scan.timestamp_s),
                    FormatDouble(scan.sensor_position.lat_deg),
                    FormatDouble(scan.sensor_position.lon_deg),
                    FormatDouble(scan.sensor_position.alt_m), FormatDouble(x.x()),
                    FormatDouble(x.y()), FormatDouble(x.z()), FormatDouble(q.w()),
                    FormatDouble(q.x()), FormatDouble(q.y()), FormatDouble(q.z())});
      if (options.lidar_scan_files) {
        WritePly((out / "survey" / scan.path).string(), per_scan[i], sensor_poses[i].Inverse());
        scan_entries.push_back(scan);
      }
    }
    csv.Close();
  }

  // Drive directories.
  SynthSummary summary;
  for (int d = first_drive; d < 2; ++d) {
    const DriveJob& job = drives[d];
    Drive drive;
    drive.dir = job.dir.string();
    drive.name = fmt::format("{}_seed{}", job.options->name, options.seed);
    drive.camera = job.options->camera;
    drive.colour = !job.options->grey;
    drive.max_gap_s = job.options->max_gap_s;
    for (int f = 0; f < static_cast<int>(job.times.size()); ++f) {
      drive.frames.push_back({f, job.times[f], FrameImage(f, *job.options)});
    }
    drive.gnss = SimulateGnss(job.path, world_frame, job.options->gnss, MixSeed(job.seed, 7));
    drive.ground_truth = GroundTruthTrack(job.path, world_frame, job.times);
    if (d == 0) drive.lidar = scan_entries;
    WriteDrive(drive, drive.dir);
    (d == 0 ? summary.num_survey_frames : summary.num_query_frames) =
        static_cast<int>(job.times.size());
  }

  WriteWorldJson(world, (out / "world.json").string());
  WriteAppearance(out.string(), options.appearance, options.world.vegetation,
                  {options.survey.render, options.query.render}, scenes,
                  {drives[0].times, drives[1].times});
  std::vector<TopViewTrack> tracks;
  for (int d = 0; d < 2; ++d) {
    TopViewTrack track;
    track.bgr = d == 0 ? cv::Scalar(200, 80, 0) : cv::Scalar(0, 0, 220);
    track.label = d == 0 ? "survey" : "query";
    for (const double t : drives[d].times) {
      track.points_in_world.push_back(drives[d].path.CamFromWorld(t).Inverse().translation);
    }
    tracks.push_back(track);
  }
  TopViewTrack scans{{}, cv::Scalar(0, 160, 0), true, "LiDAR scans"};
  for (const Rigid3d& pose : sensor_poses) scans.points_in_world.push_back(pose.translation);
  tracks.push_back(scans);
  const std::string top_view = (out / "top_view.png").string();
  if (!cv::imwrite(top_view, DrawTopView(world, tracks))) Throw("{}: cannot write image", top_view);

  summary.num_lidar_scans = static_cast<int>(sensor_poses.size());
  summary.num_lidar_points = static_cast<int64_t>(points.size());
  summary.num_surfaces = static_cast<int>(world.surfaces.size());
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace epiloc
