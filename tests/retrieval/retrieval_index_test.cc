// Whole-database retrieval end to end: a route database built by BuildDatabase (which builds the
// retrieval index), query frames of another drive placed on the route with no position prior.
#include "epiloc/survey/retrieval_index.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <thread>

#include <gtest/gtest.h>

#include "epiloc/camera/undistorter.h"
#include "epiloc/core/error.h"
#include "epiloc/feature/sift.h"
#include "epiloc/geo/route.h"
#include "epiloc/io/drive.h"
#include "epiloc/io/frame_reader.h"
#include "epiloc/io/kitti.h"
#include "epiloc/survey/build_db.h"
#include "epiloc/synth/drive_gen.h"
#include "test_util.h"

namespace epiloc {
namespace {

namespace fs = std::filesystem;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

fs::path TempDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / fmt::format("epiloc_retrieval_{}_{}", name, ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

struct Recall {
  int num_queries = 0;
  int top1 = 0;  // best match within the tolerance
  int top5 = 0;  // one of the best five within the tolerance
  double max_top1_error_m = 0.0;
};

// Places every `step`-th positioned frame of the query drive on the route of `db` by retrieval
// and compares the along-route distance of the retrieved database frames with the query's
// ground truth.
Recall MeasureRecall(const Database& db,
                     const std::string& query_dir,
                     int step,
                     double tolerance_m) {
  GlobalDescriptorModel model;
  const GlobalIndex index = LoadRetrievalIndex(db, &model);
  std::map<image_t, double> s_of_image;
  for (const DbFrame& frame : db.ReadFrames()) s_of_image[frame.image_id] = frame.s_m;
  const EnuFrame enu(*db.EnuOrigin());
  const Route route(db.ReadRoute());

  const Drive drive = LoadDrive(query_dir);
  const FramePositions truth = PositionFrames(drive, *drive.ground_truth);
  std::vector<size_t> queries;
  for (size_t i = 0; i < drive.frames.size(); i += step) {
    if (truth.per_frame[i]) queries.push_back(i);
  }
  // SIFT on the query frames in two threads (the slow part); retrieval itself is serial.
  const FrameReader reader(drive);
  const Undistorter undistorter(drive.camera);
  std::vector<Eigen::VectorXf> descriptors(queries.size());
  std::vector<std::thread> threads;
  for (size_t t = 0; t < 2; ++t) {
    threads.emplace_back([&, t] {
      for (size_t q = t; q < queries.size(); q += 2) {
        const cv::Mat image = undistorter.Undistort(reader.ReadGrey(queries[q]));
        descriptors[q] = model.Compute(ExtractSift(image, SiftOptions()).descriptors);
      }
    });
  }
  for (std::thread& thread : threads) thread.join();

  Recall recall;
  for (size_t q = 0; q < queries.size(); ++q) {
    const double s_m = route.Project(enu.ToEnu(truth.per_frame[queries[q]]->position)).s_m;
    const auto results = index.Search(descriptors[q], 5);
    bool in_top5 = false;
    for (size_t r = 0; r < results.size(); ++r) {
      const double error_m = std::abs(s_of_image.at(results[r].first) - s_m);
      if (r == 0) {
        recall.top1 += error_m <= tolerance_m;
        recall.max_top1_error_m = std::max(recall.max_top1_error_m, error_m);
      }
      in_top5 = in_top5 || error_m <= tolerance_m;
    }
    recall.top5 += in_top5;
    ++recall.num_queries;
  }
  std::printf(
      "%d queries: recall@1 %.1f %% (%d), recall@5 %.1f %% (%d) within %.0f m; worst "
      "top-1 error %.1f m\n",
      recall.num_queries, 100.0 * recall.top1 / recall.num_queries, recall.top1,
      100.0 * recall.top5 / recall.num_queries, recall.top5, tolerance_m, recall.max_top1_error_m);
  return recall;
}

TEST(SyntheticRetrieval, QueryFramesFindTheirPlaceOnTheRoute) {
  const fs::path dir = TempDir("synthetic");
  auto start = std::chrono::steady_clock::now();
  SynthOptions synth;
  synth.length_m = 120;
  synth.seed = 3;
  synth.lidar = false;
  synth.num_threads = 2;
  synth.survey.frame_rate_hz = 5;  // a database frame every 1.6 m
  synth.query.frame_rate_hz = 5;   // rendering dominates the test's time
  const SynthSummary generated = GenerateSynthetic(synth, (dir / "world").string());
  std::printf("generated %d survey and %d query frames in %.1f s\n", generated.num_survey_frames,
              generated.num_query_frames, SecondsSince(start));

  start = std::chrono::steady_clock::now();
  const std::string db_path = (dir / "route.sqlite").string();
  BuildDbOptions build;
  build.num_threads = 2;
  BuildDatabase((dir / "world" / "survey").string(), db_path, build);
  std::printf("built the database with its retrieval index in %.1f s\n", SecondsSince(start));

  {
    Database db(db_path);
    EXPECT_TRUE(HasCurrentRetrievalIndex(db));
    EXPECT_EQ(db.NumGlobalDescriptors(), db.NumFrames());
    const auto model = db.ReadRetrievalModel();
    // Re-running adds nothing and keeps the index; rebuilding it gives the same model.
    BuildDatabase((dir / "world" / "survey").string(), db_path, build);
    EXPECT_EQ(db.ReadRetrievalModel(), model);
    VocabularyOptions options;
    const RetrievalIndexSummary summary = BuildRetrievalIndex(db, options);
    EXPECT_TRUE(summary.built);
    EXPECT_EQ(summary.num_frames, db.NumFrames());
    EXPECT_EQ(summary.num_words, options.num_words);
    EXPECT_EQ(summary.dims, std::min<int64_t>(options.pca_dims, db.NumFrames() - 1));
    EXPECT_EQ(db.ReadRetrievalModel(), model);
    std::printf("retrieval index of %lld frames: %d words, %d dims, %.1f s\n",
                static_cast<long long>(summary.num_frames), summary.num_words, summary.dims,
                summary.seconds);
  }

  start = std::chrono::steady_clock::now();
  const Database db(db_path, Database::Mode::kReadOnly);
  const Recall recall = MeasureRecall(db, (dir / "world" / "query").string(), 2, 5.0);
  std::printf("queries took %.1f s\n", SecondsSince(start));
  ASSERT_GE(recall.num_queries, 30);
  EXPECT_GE(recall.top1, 0.80 * recall.num_queries);
  EXPECT_GE(recall.top5, 0.95 * recall.num_queries);
  fs::remove_all(dir);
}

TEST(SyntheticRetrieval, TooLittleDataLeavesNoIndex) {
  Database db(":memory:");
  const RetrievalIndexSummary summary = BuildRetrievalIndex(db, VocabularyOptions());
  EXPECT_FALSE(summary.built);
  EXPECT_EQ(summary.reason, "0 frames, at least 2 are needed");
  EXPECT_FALSE(db.ReadRetrievalModel().has_value());
  EXPECT_TRUE(HasCurrentRetrievalIndex(db) == false);
  try {
    LoadRetrievalIndex(db, nullptr);
    ADD_FAILURE() << "no exception";
  } catch (const Error& error) {
    EXPECT_STREQ(error.what(), ":memory:: no retrieval index in the database (build-db builds it)");
  }
}

// KITTI raw 2011_09_26 drive 0005: the left grey camera's even frames as the database, the right
// camera's odd frames as queries (0.54 m to the side, half a frame later).
TEST(KittiRetrieval, RightCameraFramesFindTheLeftCameraFrames) {
  const fs::path raw = KittiRawDrive();
  EPILOC_SKIP_UNLESS_EXISTS(raw);
  const fs::path dir = TempDir("kitti");
  KittiImportOptions import;
  import.raw_drive_dir = raw.string();
  import.camera = 0;
  import.start = 0;
  import.stop = 154;
  import.step = 2;
  import.out_dir = (dir / "cam0").string();
  ImportKitti(import);
  import.camera = 1;
  import.start = 1;
  import.out_dir = (dir / "cam1").string();
  ImportKitti(import);

  auto start = std::chrono::steady_clock::now();
  const std::string db_path = (dir / "route.sqlite").string();
  BuildDbOptions build;
  build.num_threads = 2;
  BuildDatabase((dir / "cam0").string(), db_path, build);
  std::printf("built the database with its retrieval index in %.1f s\n", SecondsSince(start));

  start = std::chrono::steady_clock::now();
  const Database db(db_path, Database::Mode::kReadOnly);
  const Recall recall = MeasureRecall(db, (dir / "cam1").string(), 1, 3.0);
  std::printf("queries took %.1f s\n", SecondsSince(start));
  ASSERT_EQ(recall.num_queries, 77);
  EXPECT_GE(recall.top1, 0.90 * recall.num_queries);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace epiloc
