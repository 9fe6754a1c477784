#include <cctype>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "cli_common.h"
#include "epiloc/cli/commands.h"
#include "epiloc/core/error.h"
#include "epiloc/core/progress.h"
#include "epiloc/eval/export.h"
#include "epiloc/io/nmea_writer.h"
#include "epiloc/io/position_readers.h"
#include "epiloc/localize/stream.h"

namespace epiloc {
namespace {

// The position an NMEA consumer should get for a frame: the 6-DoF pose when it was accepted,
// else the online estimate; none for a frame that was not localized.
std::optional<ResultRow> BestRow(const std::vector<ResultRow>& rows) {
  std::optional<ResultRow> online;
  for (const ResultRow& row : rows) {
    if (row.status != ResultStatus::kOk || !row.has_position) continue;
    if (row.method == "pnp") return row;
    if (row.method == "online") online = row;
  }
  return online;
}

bool LooksLikeNmea(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension == ".nmea" || extension == ".nmea0183" || extension == ".log";
}

}  // namespace

int RunLocalize(int argc, char** argv) {
  CLI::App app(
      "Localize a drive along the route of a database, frame by frame: epipolar distance to "
      "database frames, DTW alignment and V-fit (Kyutoku et al.), 6-DoF refinement against the "
      "survey's 3-D points. Input: a recorded drive, a drive still being recorded (--follow), or "
      "a video file / camera (--video). Writes the result CSV that `epiloc evaluate` reads, row "
      "by row as frames are done.",
      "localize");
  CommonFlags flags;
  AddCommonFlags(app, flags);
  std::string db_path, drive_dir, out_path, geojson_path, diagnostics_path, nmea_path,
      mode = "online";
  std::string video, calibration, gnss_path, gnss_format = "auto", gnss_date;
  double idle_timeout_s = 10.0;
  std::optional<double> video_start_s;
  int64_t max_frames = -1;
  bool follow = false;
  LocalizeOptions options;
  bool no_gps = false;
  app.add_option("--db", db_path, "Route database (SQLite)")->required();
  app.add_option("--drive", drive_dir, "Drive directory to localize");
  app.add_flag("--follow", follow,
               "The drive is still being recorded: rows appended to its frames CSV (and GNSS "
               "file) are localized as they appear; ends after --idle-timeout-s without a frame");
  app.add_option("--max-latency-s", options.max_latency_s,
                 "Live input: skip a frame that would come out this late while a newer one is "
                 "waiting (rows with status skipped); 0 tracks every frame")
      ->capture_default_str();
  app.add_option("--idle-timeout-s", idle_timeout_s,
                 "With --follow: stop after this many seconds without a new frame")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--video", video,
                 "Read frames from a video file or a camera device number (OpenCV), instead of "
                 "--drive; needs --calibration");
  app.add_option("--calibration", calibration,
                 "With --video: a drive.json-style file whose \"camera\" object is the "
                 "calibration");
  app.add_option("--gnss", gnss_path, "With --video: GNSS positions (position CSV or NMEA log)");
  app.add_option("--gnss-format", gnss_format,
                 "Format of --gnss: auto (by extension: .nmea/.nmea0183/.log = nmea), csv, nmea")
      ->check(CLI::IsMember({"auto", "csv", "nmea"}))
      ->capture_default_str();
  app.add_option("--gnss-date", gnss_date,
                 "With an NMEA --gnss without RMC sentences: the date, YYYY-MM-DD");
  app.add_option("--video-start-s", video_start_s,
                 "With a --video file: UNIX time of its first frame (default: the first GNSS "
                 "sample's time, else 0); a camera's frames get the clock time");
  app.add_option("--max-frames", max_frames, "With --video: stop after this many frames");
  app.add_option("--out", out_path, "Result CSV ('-': standard output, row by row)")->required();
  app.add_option("--nmea-out", nmea_path,
                 "Also write a GGA and an RMC sentence per localized frame (fix quality 6: not "
                 "GNSS); '-' for standard output");
  app.add_option("--mode", mode, "fixed (both ends aligned), free (end free) or online (causal)")
      ->check(CLI::IsMember({"fixed", "free", "online"}))
      ->capture_default_str();
  app.add_flag("--no-gps", no_gps, "Do not use the drive's GNSS (image retrieval places it)");
  app.add_flag("--all-methods", options.all_methods,
               "Write gps, nearest, dtw_fixed, fit_fixed, dtw_free, fit_free and online rows "
               "(the offline ones when the input ends)");
  app.add_option("--geojson", geojson_path, "Also write the estimates as GeoJSON (at the end)");
  app.add_option("--diagnostics", diagnostics_path,
                 "Per-pair diagnostics CSV (d values, inliers, fit residuals)");
  app.add_option("--threads", options.num_threads, "Threads (0 = one per core)")
      ->capture_default_str();
  app.add_option("--gps-window-m", options.gps_window_m,
                 "Search half-width around the GPS prior when (re)initialising")
      ->capture_default_str();
  app.add_option("--track-window-m", options.track_window_m,
                 "Half-width of the database window evaluated around the predicted position")
      ->capture_default_str();
  app.add_option("--max-sigma-m", options.max_sigma_m,
                 "A frame whose along-track sigma exceeds this is lost, not a guess")
      ->capture_default_str();
  app.add_option("--survey-sigma-m", options.survey_sigma_m,
                 "Error of the survey positions, added to every reported sigma (0: exact)")
      ->capture_default_str();
  app.add_option("--viewpoint-sigma-ratio", options.viewpoint_sigma_ratio,
                 "6-DoF horizontal sigma added per metre of offset from the survey's line")
      ->capture_default_str();
  app.add_option("--off-route-m", options.off_route_m,
                 "A GPS fix this far beside or beyond the route marks the frame off_route")
      ->capture_default_str();
  app.add_option("--route-end-margin-m", options.route_end_margin_m,
                 "A track this far beyond the first or last database frame is off_route")
      ->capture_default_str();
  app.add_option("--fit-window-m", options.fit_window_m,
                 "Database frames within this of the DTW match enter the V-fit")
      ->capture_default_str();
  app.add_option("--max-focal-ratio", options.max_focal_ratio,
                 "Query images are reduced to at most this times the database's focal length "
                 "(0: full resolution)")
      ->capture_default_str();
  app.add_option("--max-query-features", options.max_query_features,
                 "Strongest SIFT features of a query frame")
      ->capture_default_str();
  app.add_option("--query-max-image-size", options.sift.max_image_size,
                 "Query frames whose longer side exceeds this are downscaled for SIFT (0 = never)")
      ->capture_default_str();
  app.add_option("--query-upsampled-octave", options.sift.upsampled_octave,
                 "Query SIFT also detects in the upsampled octave (finest features, ~2.5x the "
                 "extraction time)")
      ->capture_default_str();
  std::string robust = "fast";
  app.add_option("--ransac", robust,
                 "Robust essential-matrix estimator per pair: fast (USAC LO-RANSAC) or magsac "
                 "(MAGSAC++, slower)")
      ->check(CLI::IsMember({"fast", "magsac"}))
      ->capture_default_str();
  std::string matcher = "window";
  app.add_option("--matcher", matcher,
                 "window: one FLANN search per query frame over its database window; pairs: one "
                 "search per query/database pair (slower, reference)")
      ->check(CLI::IsMember({"window", "pairs"}))
      ->capture_default_str();
  app.add_option(
         "--window-checks", options.pairs.window_checks,
         "Distances computed per query descriptor over the tracking window (speed / recall)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--match-checks", options.pairs.match.num_checks,
                 "With --matcher pairs: distances computed per descriptor search (speed / recall)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-db-features", options.pairs.max_db_features,
                 "Strongest database features per frame")
      ->capture_default_str();
  app.add_option("--dtw-max-step", options.dtw.max_step,
                 "Most database frames a query frame may advance")
      ->capture_default_str();
  std::string refine = "pnp";
  app.add_option("--refine", refine,
                 "pnp: 6-DoF pose against the survey's 3-D points (pnp rows; needs a triangulated "
                 "database) | none")
      ->check(CLI::IsMember({"pnp", "none"}))
      ->capture_default_str();
  app.add_option("--refine-max-disagreement-m", options.refine.max_along_disagreement_m,
                 "PnP poses farther along the route from the epipolar estimate are rejected")
      ->capture_default_str();
  app.add_option("--refine-max-error-px", options.refine.pnp.max_reprojection_px,
                 "PnP RANSAC inlier threshold of the refinement, pixels")
      ->capture_default_str();
  app.add_option("--refine-min-inliers", options.refine.min_inliers,
                 "Fewer PnP inliers: the epipolar estimate is kept (flagged thin)")
      ->capture_default_str();
  if (auto code = Parse(app, flags, argc, argv)) return *code;
  if (video.empty() == drive_dir.empty()) Throw("give one of --drive or --video");
  if (follow && drive_dir.empty()) Throw("--follow applies to --drive");
  if (!video.empty() && calibration.empty()) Throw("--video needs --calibration");
  if (video.empty() &&
      (!calibration.empty() || !gnss_path.empty() || video_start_s || max_frames >= 0)) {
    Throw("--calibration, --gnss, --video-start-s and --max-frames apply to --video");
  }
  options.refine.enabled = refine == "pnp";
  options.mode = ParseMode(mode);
  options.use_gps = !no_gps;
  options.pairs.window_matching = matcher == "window";
  options.pairs.epipole.robust =
      robust == "fast" ? EpipoleOptions::Robust::kFast : EpipoleOptions::Robust::kMagsac;
  options.record_offline = options.WantsOffline();
  options.diagnostics = !diagnostics_path.empty();
  options.Check();
  CheckCommandOutputs({{"--out", out_path},
                       {"--nmea-out", nmea_path},
                       {"--geojson", geojson_path},
                       {"--diagnostics", diagnostics_path}},
                      {{"--db", db_path},
                       {"--drive", drive_dir},
                       {"--video", video},
                       {"--calibration", calibration},
                       {"--gnss", gnss_path}});

  std::unique_ptr<FrameSource> source;
  if (!video.empty()) {
    VideoSourceOptions video_options;
    video_options.max_frames = max_frames;
    if (!gnss_path.empty() && options.use_gps) {
      const PositionFormat format =
          gnss_format == "nmea" || (gnss_format == "auto" && LooksLikeNmea(gnss_path))
              ? PositionFormat::kNmea
              : PositionFormat::kCsv;
      video_options.gnss = ReadPositions(gnss_path, format, std::nullopt, gnss_date);
      EPILOC_CHECK(!video_options.gnss.samples.empty(), "{}: no GNSS positions", gnss_path);
    } else if (options.use_gps) {
      Throw("--video without --gnss: give --gnss FILE or --no-gps");
    }
    video_options.start_time_s = video_start_s;
    if (!video_start_s && !video_options.gnss.samples.empty()) {
      video_options.start_time_s = video_options.gnss.samples.front().timestamp_s;
    }
    source = std::make_unique<VideoFrameSource>(video, ReadCalibrationFile(calibration),
                                                std::move(video_options));
  } else if (follow) {
    source = std::make_unique<FollowDriveSource>(drive_dir, options.use_gps, idle_timeout_s);
  } else {
    source = std::make_unique<DriveFrameSource>(drive_dir, options.use_gps);
  }

  Localizer localizer(db_path, source->camera(), options);
  ResultCsvWriter out(out_path, Localizer::ExtraColumns(), localizer.refining());
  std::unique_ptr<NmeaWriter> nmea;
  if (!nmea_path.empty()) nmea = std::make_unique<NmeaWriter>(nmea_path);
  std::unique_ptr<DiagnosticsCsv> diagnostics;
  if (!diagnostics_path.empty()) {
    diagnostics = std::make_unique<DiagnosticsCsv>(diagnostics_path, localizer);
  }
  ResultTable all_rows;  // for --geojson
  all_rows.extra_columns = Localizer::ExtraColumns();

  // With the results on standard output, the progress bar and the summary go to stderr only.
  Progress progress("localize", 0);
  const LocalizeRun run = LocalizeStream(
      localizer, *source,
      [&](const FrameEstimate* estimate, const std::vector<ResultRow>& rows) {
        for (const ResultRow& row : rows) out.Write(row);
        out.Flush();
        if (estimate && nmea) {
          if (const std::optional<ResultRow> best = BestRow(rows)) {
            nmea->Write(best->timestamp_s, best->position);
          }
        }
        if (estimate && diagnostics) diagnostics->Write(*estimate);
        if (!geojson_path.empty()) {
          all_rows.rows.insert(all_rows.rows.end(), rows.begin(), rows.end());
        }
      },
      progress.Callback());
  progress.Finish();
  out.Close();
  if (nmea) nmea->Close();
  if (diagnostics) diagnostics->Close();
  if (!geojson_path.empty()) {
    ExportOptions geojson;
    geojson.format = TrajectoryFormat::kGeoJson;
    ExportTrajectory(all_rows, geojson, geojson_path);
  }
  std::FILE* summary = out_path == "-" || nmea_path == "-" ? stderr : stdout;
  std::fprintf(summary,
               "%s: %d frames, %d localized online, %d (re)initialisations, %lld pairs, %.1f s "
               "(%.1f frames/s; per frame: extraction %.1f ms, tracking %.1f ms; latency p50 "
               "%.0f ms, p95 %.0f ms, max %.0f ms)\n",
               source->name().c_str(), run.num_frames, run.num_localized_online,
               run.num_reinitialisations, static_cast<long long>(run.num_pairs), run.seconds,
               run.frames_per_second,
               run.num_frames ? 1e3 * run.extraction_seconds / run.num_frames : 0.0,
               run.num_frames ? 1e3 * run.tracking_seconds / run.num_frames : 0.0,
               1e3 * run.latency_p50_s, 1e3 * run.latency_p95_s, 1e3 * run.latency_max_s);
  if (run.num_skipped > 0) {
    std::fprintf(summary, "%s: %d late frames skipped (--max-latency-s %.3g)\n",
                 source->name().c_str(), run.num_skipped, options.max_latency_s);
  }
  if (run.num_frames > 0) {
    const double n = run.num_frames;
    const StageSeconds& st = run.stages;
    std::fprintf(summary,
                 "%s: per frame by stage [ms]: read %.1f, undistort %.1f, sift %.1f, retrieval "
                 "%.1f | window %.1f (%.1f of it between frames), match %.1f, geometry %.1f, "
                 "refine %.1f, other %.1f\n",
                 source->name().c_str(), 1e3 * st.read / n, 1e3 * st.undistort / n,
                 1e3 * st.sift / n, 1e3 * st.retrieval / n, 1e3 * st.window / n,
                 1e3 * run.maintenance_seconds / n, 1e3 * st.match / n,
                 1e3 * st.geometry / n, 1e3 * st.refine / n, 1e3 * st.other / n);
  }
  if (run.refined) {
    std::fprintf(summary,
                 "%s: 6-DoF refinement: %d frames refined, %d thin structure, %d rejected "
                 "(epipolar estimate kept, flagged)\n",
                 source->name().c_str(), run.num_refined_ok, run.num_refine_thin,
                 run.num_refine_rejected);
  }
  return kExitOk;
}

}  // namespace epiloc
