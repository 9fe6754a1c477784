#include "epiloc/localize/window_matcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <set>
#include <thread>
#include <utility>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "epiloc/core/error.h"
#include "epiloc/feature/matcher.h"
#include "epiloc/feature/sift.h"

namespace epiloc {
namespace {

constexpr int kWidth = 900, kHeight = 560;  // frame size, pixels
constexpr int kNumDbFrames = 11;
constexpr int kFeatures = 2000;  // SIFT may return a few more (ties): rows are cut to this

// A database or query frame: a view of one large texture through a known affine map.
struct View {
  cv::Mat frame_from_texture;  // 2x3, texture pixels -> frame pixels
  FeatureSet features;
  std::shared_ptr<const FeatureDescriptors> descriptors;
};

cv::Mat Texture(int width, int height, uint64_t seed) {
  std::mt19937_64 rng(seed);
  cv::Mat image(height, width, CV_8UC1, cv::Scalar(128));
  std::uniform_int_distribution<int> x(0, width - 1), y(0, height - 1), r(2, 14), v(0, 255);
  for (int i = 0; i < 6000; ++i) {
    cv::circle(image, cv::Point(x(rng), y(rng)), r(rng), cv::Scalar(v(rng)), cv::FILLED);
  }
  return image;
}

View MakeView(const cv::Mat& texture, double angle_deg, double scale, double dx, double dy) {
  const cv::Point2f centre(texture.cols / 2.0f, texture.rows / 2.0f);
  View view;
  view.frame_from_texture = cv::getRotationMatrix2D(centre, angle_deg, scale);
  view.frame_from_texture.at<double>(0, 2) += kWidth / 2.0 - centre.x + dx;
  view.frame_from_texture.at<double>(1, 2) += kHeight / 2.0 - centre.y + dy;
  cv::Mat frame;
  cv::warpAffine(texture, frame, view.frame_from_texture, cv::Size(kWidth, kHeight));
  SiftOptions sift;
  sift.max_num_features = kFeatures;
  view.features = ExtractSift(frame, sift);
  const int rows = std::min(view.features.size(), kFeatures);
  view.features.keypoints.conservativeResize(rows, Eigen::NoChange);
  view.features.descriptors.conservativeResize(rows, Eigen::NoChange);
  view.descriptors = std::make_shared<const FeatureDescriptors>(view.features.descriptors);
  return view;
}

// A query and database views sharing most of their content, built once for all tests.
class WindowMatcherTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const cv::Mat texture = Texture(1300, 860, 7);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> angle(-4, 4), scale(0.95, 1.05), shift(-70, 70);
    query_ = new View(MakeView(texture, angle(rng), scale(rng), shift(rng), shift(rng)));
    db_ = new std::vector<View>();
    for (int f = 0; f < kNumDbFrames; ++f) {
      db_->push_back(MakeView(texture, angle(rng), scale(rng), shift(rng), shift(rng)));
    }
  }
  static void TearDownTestSuite() {
    delete query_;
    delete db_;
  }

  static WindowMatcher::LoadFn Loader(int max_rows) {
    return [max_rows](int db_index) {
      const FeatureDescriptors& all = *db_->at(db_index).descriptors;
      if (max_rows < 0 || max_rows >= all.rows()) return db_->at(db_index).descriptors;
      return std::make_shared<const FeatureDescriptors>(all.topRows(max_rows));
    };
  }

  // Whether query row q and database row r of frame f are the same texture point (2 px).
  static bool Correct(int f, int q, int r) {
    cv::Mat texture_from_query;
    cv::invertAffineTransform(query_->frame_from_texture, texture_from_query);
    const cv::Mat& a = (*db_)[f].frame_from_texture;
    const double xq = query_->features.keypoints(q, 0), yq = query_->features.keypoints(q, 1);
    const cv::Mat& t = texture_from_query;
    const double xt = t.at<double>(0, 0) * xq + t.at<double>(0, 1) * yq + t.at<double>(0, 2);
    const double yt = t.at<double>(1, 0) * xq + t.at<double>(1, 1) * yq + t.at<double>(1, 2);
    const double x = a.at<double>(0, 0) * xt + a.at<double>(0, 1) * yt + a.at<double>(0, 2);
    const double y = a.at<double>(1, 0) * xt + a.at<double>(1, 1) * yt + a.at<double>(1, 2);
    const FeatureKeypoints& k = (*db_)[f].features.keypoints;
    return std::hypot(x - k(r, 0), y - k(r, 1)) < 2.0;
  }

  static View* query_;
  static std::vector<View>* db_;
};

View* WindowMatcherTest::query_ = nullptr;
std::vector<View>* WindowMatcherTest::db_ = nullptr;

struct Agreement {
  int window = 0;         // window matches
  int pairs = 0;          // per-pair matches
  int pairs_correct = 0;  // per-pair matches that are geometrically correct
  int common = 0;         // window matches that the per-pair matcher found too
  int correct = 0;        // window matches that are geometrically correct

  double Common() const { return common / std::max(1.0, std::max(window, pairs) * 1.0); }
  double Correct() const { return correct / std::max(1.0, window * 1.0); }
};

// Compares, per database frame, the window matcher with the per-pair matcher (query indexed, as
// the localizer does); `correct(f, q, r)` says whether query row q and row r of frame f match.
std::vector<Agreement> Compare(const WindowMatcher& matcher,
                               const FeatureDescriptors& query,
                               const std::vector<View>& db,
                               int checks,
                               const std::function<bool(int, int, int)>& correct) {
  const DescriptorIndex query_index(query, MatchOptions());
  const auto matches = matcher.Match(query, -1, MatchOptions().ratio, checks);
  std::vector<Agreement> frames;
  for (int f : matcher.Window()) {
    Agreement frame;
    std::set<std::pair<int, int>> pairs;
    for (const FeatureMatch& m : query_index.Match(*db[f].descriptors)) {
      pairs.insert({m.index_a, m.index_b});
      frame.pairs_correct += correct(f, m.index_a, m.index_b);
    }
    frame.pairs = static_cast<int>(pairs.size());
    std::set<int> db_rows;
    for (const WindowMatch& m : matches.at(f)) {
      EXPECT_TRUE(db_rows.insert(m.db_row).second) << "database row matched twice";
      ++frame.window;
      frame.common += pairs.count({m.query_row, m.db_row});
      frame.correct += correct(f, m.query_row, m.db_row);
    }
    frames.push_back(frame);
  }
  return frames;
}

TEST_F(WindowMatcherTest, AgreesWithPerPairMatching) {
  ASSERT_EQ(query_->features.size(), kFeatures);
  WindowMatcher matcher;
  matcher.SetWindow({0, 1, 2, 3, 4, 5, 6, 7}, Loader(-1));
  EXPECT_EQ(matcher.NumDescriptors(), 8 * kFeatures);
  for (int checks : {32, 64, 128}) {
    const std::vector<Agreement> frames =
        Compare(matcher, query_->features.descriptors, *db_, checks, Correct);
    Agreement total;
    double min_common = 1, min_correct = 1;
    for (const Agreement& a : frames) {
      total.window += a.window;
      total.pairs += a.pairs;
      total.pairs_correct += a.pairs_correct;
      total.common += a.common;
      total.correct += a.correct;
      min_common = std::min(min_common, a.Common());
      min_correct = std::min(min_correct, a.Correct());
    }
    std::cout << "checks " << checks << ": window " << total.window << " matches, per-pair "
              << total.pairs << " (" << total.pairs_correct << " correct); common " << total.common
              << " (" << 100 * total.Common() << " %, worst frame " << 100 * min_common
              << " %), correct " << total.correct << " (" << 100 * total.Correct()
              << " %, worst frame " << 100 * min_correct << " %)\n";
    // Fewer checks miss more true neighbours (32: about 94 % correct, 93 % in common).
    if (checks >= 64) {
      EXPECT_GT(total.window, 8 * 300);
      EXPECT_GE(min_common, 0.85);
      EXPECT_GE(total.Correct(), 0.95);  // about 96.5 %; the per-pair matcher's is 98 %
    }
    if (checks >= 128) {
      // FLANN seeds its trees from std::random_device: over 48 runs the worst frame ranged from
      // 94.9 % to 96.5 % correct, so the bound sits below that spread.
      EXPECT_GE(min_correct, 0.93);
    }
  }
}

TEST_F(WindowMatcherTest, SlidingWindowEqualsFreshMatcher) {
  // With K >= the window's descriptors the search is exhaustive, so the incremental index must
  // give exactly what a freshly built one gives.
  constexpr int kRows = 100;
  WindowMatcherOptions options;
  options.max_neighbors = 8 * kRows;
  options.num_trees = 1;  // exhaustive search visits every tree in full
  WindowMatcher sliding(options);
  std::mt19937_64 rng(5);
  int start = 0, size = 4, incremental = 0;
  for (int step = 0; step < 50; ++step) {
    std::uniform_int_distribution<int> move(-1, 2), resize(-1, 1), jump(0, 9);
    if (jump(rng) == 0) {
      start = std::uniform_int_distribution<int>(0, kNumDbFrames - 1)(rng);
    } else {
      start += move(rng);
    }
    size = std::clamp(size + resize(rng), 2, 7);
    start = std::clamp(start, 0, kNumDbFrames - size);
    std::vector<int> window;
    for (int f = start + size - 1; f >= start; --f) window.push_back(f);  // any order
    const int rebuilds = sliding.NumRebuilds();
    sliding.SetWindow(window, Loader(kRows));
    incremental += sliding.NumRebuilds() == rebuilds;
    WindowMatcher fresh(options);
    fresh.SetWindow(window, Loader(kRows));
    ASSERT_EQ(sliding.Window(), fresh.Window());
    ASSERT_EQ(sliding.NumDescriptors(), size * kRows);
    const auto a = sliding.Match(query_->features.descriptors, 400, 0.8, 64);
    const auto b = fresh.Match(query_->features.descriptors, 400, 0.8, 64);
    ASSERT_EQ(a.size(), static_cast<size_t>(size));
    for (int f : window) {
      const std::vector<WindowMatch>& ma = a.at(f);
      const std::vector<WindowMatch>& mb = b.at(f);
      ASSERT_EQ(ma.size(), mb.size()) << "step " << step << " frame " << f;
      EXPECT_GT(ma.size(), 20u);
      for (size_t i = 0; i < ma.size(); ++i) {
        EXPECT_EQ(ma[i].query_row, mb[i].query_row);
        EXPECT_EQ(ma[i].db_row, mb[i].db_row);
        EXPECT_EQ(ma[i].distance, mb[i].distance);
      }
    }
  }
  std::cout << "rebuilds " << sliding.NumRebuilds() << ", incremental updates " << incremental
            << "\n";
  EXPECT_GT(sliding.NumRebuilds(), 2);
  EXPECT_GT(incremental, 20);
}

TEST_F(WindowMatcherTest, DeferredRebuildsWaitForTheOwner) {
  // With defer_rebuilds, SetWindow only updates the index (it builds one when there is none);
  // RebuildDue says when the rule asks for a build, and Rebuild gives the index a fresh matcher
  // builds over the same window (the same searches, bit for bit).
  constexpr int kRows = 100;
  WindowMatcherOptions options;
  options.defer_rebuilds = true;
  WindowMatcher deferred(options);
  EXPECT_FALSE(deferred.RebuildDue());
  deferred.SetWindow({0, 1, 2, 3}, Loader(kRows));
  EXPECT_EQ(deferred.NumRebuilds(), 1);  // the first index
  EXPECT_FALSE(deferred.RebuildDue());
  int due_at = -1;
  for (int start = 1; start <= 6; ++start) {
    deferred.SetWindow({start, start + 1, start + 2, start + 3}, Loader(kRows));
    EXPECT_EQ(deferred.NumRebuilds(), 1) << "SetWindow rebuilt at start " << start;
    if (due_at < 0 && deferred.RebuildDue()) due_at = start;
  }
  // Three of the four frames replaced: 300 removed of 700 rows (rule: > 0.5 of the rows or
  // more than twice the built size) is not due; four replaced (400 of 800) not; five: 500 of 900.
  EXPECT_EQ(due_at, 5);
  ASSERT_TRUE(deferred.RebuildDue());
  deferred.Rebuild();
  EXPECT_EQ(deferred.NumRebuilds(), 2);
  EXPECT_FALSE(deferred.RebuildDue());
  EXPECT_EQ(deferred.NumDescriptors(), 4 * kRows);
  WindowMatcherOptions fresh_options;
  WindowMatcher fresh(fresh_options);
  fresh.SetWindow({6, 7, 8, 9}, Loader(kRows));
  ASSERT_EQ(deferred.Window(), fresh.Window());
  const auto a = deferred.Match(query_->features.descriptors, 400, 0.8, 64);
  const auto b = fresh.Match(query_->features.descriptors, 400, 0.8, 64);
  for (int f : fresh.Window()) {
    ASSERT_EQ(a.at(f).size(), b.at(f).size()) << "frame " << f;
    EXPECT_GT(a.at(f).size(), 20u);
    for (size_t i = 0; i < a.at(f).size(); ++i) {
      EXPECT_EQ(a.at(f)[i].query_row, b.at(f)[i].query_row);
      EXPECT_EQ(a.at(f)[i].db_row, b.at(f)[i].db_row);
      EXPECT_EQ(a.at(f)[i].distance, b.at(f)[i].distance);
    }
  }
}

TEST_F(WindowMatcherTest, ConcurrentMatchesGiveTheSequentialResult) {
  WindowMatcher matcher;
  matcher.SetWindow({1, 2, 3, 4}, Loader(500));
  const FeatureDescriptors& query = query_->features.descriptors;
  const auto sequential = matcher.Match(query, 1000, 0.8, 64);  // the search is deterministic
  std::vector<std::unordered_map<int, std::vector<WindowMatch>>> results(3);
  std::vector<std::thread> threads;
  for (auto& result : results) {
    threads.emplace_back([&] { result = matcher.Match(query, 1000, 0.8, 64); });
  }
  for (std::thread& thread : threads) thread.join();
  for (const auto& result : results) {
    ASSERT_EQ(result.size(), sequential.size());
    for (const auto& [db_index, matches] : sequential) {
      const std::vector<WindowMatch>& other = result.at(db_index);
      ASSERT_EQ(other.size(), matches.size());
      for (size_t i = 0; i < matches.size(); ++i) {
        EXPECT_EQ(other[i].query_row, matches[i].query_row);
        EXPECT_EQ(other[i].db_row, matches[i].db_row);
      }
    }
  }
}

TEST_F(WindowMatcherTest, RejectsBadInputAndKeepsTheWindow) {
  WindowMatcher matcher;
  EXPECT_TRUE(matcher.Match(query_->features.descriptors, -1, 0.8, 64).empty());
  matcher.SetWindow({2, 3}, Loader(200));
  EXPECT_THROW(matcher.SetWindow({3, 3}, Loader(200)), Error);
  EXPECT_THROW(matcher.SetWindow({-1, 3}, Loader(200)), Error);
  EXPECT_THROW(matcher.SetWindow({3, 4}, [](int) { return nullptr; }), Error);
  EXPECT_EQ(matcher.Window(), (std::vector<int>{2, 3}));
  EXPECT_EQ(matcher.NumDescriptors(), 400);
  EXPECT_THROW(matcher.Match(query_->features.descriptors, -1, 1.5, 64), Error);
  EXPECT_THROW(matcher.Match(query_->features.descriptors, -1, 0.8, 0), Error);
  EXPECT_TRUE(matcher.Match(query_->features.descriptors, 0, 0.8, 64).at(2).empty());
  matcher.SetWindow({}, Loader(200));
  EXPECT_EQ(matcher.NumDescriptors(), 0);
  EXPECT_TRUE(matcher.Match(query_->features.descriptors, -1, 0.8, 64).empty());
  WindowMatcherOptions bad;
  bad.max_neighbors = 1;
  EXPECT_THROW(WindowMatcher{bad}, Error);
}

// A benchmark, not a test: prints the per-query-frame cost of both matchers (the fastest of a
// few repeats, interleaved, as other work may share the machine).
TEST_F(WindowMatcherTest, PrintsSpeed) {
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  };
  constexpr int kWindow = 10, kRepeats = 5, kSlides = 40;
  std::vector<int> window;
  for (int f = 0; f < kWindow; ++f) window.push_back(f);
  WindowMatcher matcher;
  auto t0 = Clock::now();
  matcher.SetWindow(window, Loader(-1));
  const double build_ms = ms(t0);
  // Slide back and forth by one frame: one frame leaves, one enters, a full build now and then.
  t0 = Clock::now();
  for (int slide = 0; slide < kSlides; ++slide) {
    for (int& f : window) f += slide % 2 == 0 ? 1 : -1;
    matcher.SetWindow(window, Loader(-1));
  }
  const double slide_ms = ms(t0) / kSlides;
  const int rebuilds = matcher.NumRebuilds() - 1;

  const FeatureDescriptors& query = query_->features.descriptors;
  t0 = Clock::now();
  const DescriptorIndex query_index(query, MatchOptions());
  const double index_ms = ms(t0);
  const std::vector<int> checks = {32, 64, 128};
  double pairs_ms = 1e9;
  std::vector<double> window_ms(checks.size(), 1e9);
  for (int r = 0; r < kRepeats; ++r) {
    t0 = Clock::now();
    for (int f : window) query_index.Match(*(*db_)[f].descriptors);
    pairs_ms = std::min(pairs_ms, ms(t0));
    for (size_t c = 0; c < checks.size(); ++c) {
      t0 = Clock::now();
      matcher.Match(query, -1, 0.8, checks[c]);
      window_ms[c] = std::min(window_ms[c], ms(t0));
    }
  }
  std::cout << "per query frame, " << query.rows() << " query features x " << kWindow
            << " database frames x " << (*db_)[0].descriptors->rows() << " features:\n"
            << "  per-pair: query index " << index_ms << " ms + " << kWindow
            << " x DescriptorIndex::Match " << pairs_ms << " ms\n"
            << "  window: full build " << build_ms << " ms; SetWindow sliding by one frame "
            << slide_ms << " ms on average (" << rebuilds << " full builds in " << kSlides
            << " slides)\n";
  for (size_t c = 0; c < checks.size(); ++c) {
    std::cout << "  window: Match with checks " << checks[c] << ": " << window_ms[c] << " ms\n";
  }
}

}  // namespace
}  // namespace epiloc
