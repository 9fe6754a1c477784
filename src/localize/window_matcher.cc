#include "epiloc/localize/window_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <thread>

#include "epiloc/core/error.h"
#include "epiloc/feature/kd_forest.h"
#include "epiloc/feature/matcher.h"

namespace epiloc {

void WindowMatcherOptions::Check() const {
  EPILOC_CHECK(num_trees >= 1, "window matcher: num_trees must be >= 1, got {}", num_trees);
  EPILOC_CHECK(leaf_size >= 1, "window matcher: leaf_size must be >= 1, got {}", leaf_size);
  EPILOC_CHECK(max_neighbors >= 2, "window matcher: max_neighbors must be >= 2, got {}",
               max_neighbors);
  EPILOC_CHECK(rebuild_fraction > 0 && rebuild_fraction < 1,
               "window matcher: rebuild_fraction must be in (0, 1), got {}", rebuild_fraction);
}

namespace {

using RootSift = std::vector<float>;

// A window frame's RootSIFT rows, kept for the next full build (the forest holds its own 8-bit
// copy).
struct Frame {
  std::shared_ptr<const RootSift> buffer;  // owns `rows`
  const float* rows = nullptr;             // num_rows x 128
  int num_rows = 0;
  size_t first_id = 0;  // forest point id of row 0; rows have consecutive ids
  int slot = -1;        // dense frame number used by Match
};

struct PointRef {
  int slot;
  int row;
};

}  // namespace

struct WindowMatcher::Impl {
  std::unique_ptr<KdForest> index;
  std::map<int, Frame> frames;     // the window, by database index
  std::vector<int> slot_db_index;  // -1 = free slot
  // Forest point id -> (frame slot, row) for every point added since the last full build. The
  // forest numbers points in insertion order and keeps the numbers across removals.
  std::vector<PointRef> points;
  size_t num_removed = 0;  // removed points still in the trees
  size_t built_size = 0;   // points at the last full build
  int rebuilds = 0;

  int TakeSlot(int db_index) {
    auto free = std::find(slot_db_index.begin(), slot_db_index.end(), -1);
    if (free != slot_db_index.end()) {
      *free = db_index;
      return static_cast<int>(free - slot_db_index.begin());
    }
    slot_db_index.push_back(db_index);
    return static_cast<int>(slot_db_index.size()) - 1;
  }

  void AppendPoints(Frame& frame) {
    frame.first_id = points.size();
    for (int r = 0; r < frame.num_rows; ++r) points.push_back({frame.slot, r});
  }

  // The rule of WindowMatcherOptions::rebuild_fraction for an index of `total` points of which
  // `removed` are removed.
  bool Unbalanced(size_t total, size_t removed, double fraction) const {
    return static_cast<double>(removed) > fraction * static_cast<double>(total) ||
           total > 2 * built_size;
  }

  // Full build over `window` (which becomes the window): its rows, in database index order, in
  // one contiguous block.
  void Build(std::map<int, Frame> window, int num_trees, int leaf_size) {
    index.reset();
    size_t rows = 0;
    for (const auto& [db_index, frame] : window) rows += static_cast<size_t>(frame.num_rows);
    auto block = std::make_shared<RootSift>(rows * 128);
    slot_db_index.clear();
    points.clear();
    size_t offset = 0;
    for (auto& [db_index, frame] : window) {
      std::copy_n(frame.rows, static_cast<size_t>(frame.num_rows) * 128, block->data() + offset);
      frame.rows = block->data() + offset;
      frame.buffer = block;
      frame.slot = TakeSlot(db_index);
      AppendPoints(frame);
      offset += static_cast<size_t>(frame.num_rows) * 128;
    }
    frames = std::move(window);
    num_removed = 0;
    built_size = points.size();
    if (!points.empty()) {
      index = std::make_unique<KdForest>(num_trees, KdForest::kDefaultSeed, leaf_size);
      index->Build(block->data(), points.size());
    }
    ++rebuilds;
  }
};

WindowMatcher::WindowMatcher(const WindowMatcherOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  options_.Check();
}

WindowMatcher::~WindowMatcher() = default;

void WindowMatcher::SetWindow(const std::vector<int>& db_indices, const LoadFn& load) {
  std::vector<int> wanted = db_indices;
  std::sort(wanted.begin(), wanted.end());
  EPILOC_CHECK(wanted.empty() || wanted.front() >= 0, "window matcher: negative database index {}",
               wanted.empty() ? 0 : wanted.front());
  const auto duplicate = std::adjacent_find(wanted.begin(), wanted.end());
  EPILOC_CHECK(duplicate == wanted.end(), "window matcher: database index {} listed twice",
               duplicate == wanted.end() ? 0 : *duplicate);
  Impl& impl = *impl_;

  // Load first: a failing load leaves the matcher as it was.
  std::map<int, Frame> entering;
  size_t entering_rows = 0;
  for (int db_index : wanted) {
    if (impl.frames.count(db_index) > 0) continue;
    const std::shared_ptr<const FeatureDescriptors> descriptors = load(db_index);
    EPILOC_CHECK(descriptors != nullptr, "window matcher: no descriptors for database index {}",
                 db_index);
    Frame frame;
    frame.num_rows = static_cast<int>(descriptors->rows());
    auto buffer = std::make_shared<RootSift>(ToRootSift(*descriptors, frame.num_rows));
    frame.rows = buffer->data();
    frame.buffer = std::move(buffer);
    entering_rows += frame.num_rows;
    entering.emplace(db_index, std::move(frame));
  }
  std::vector<int> leaving;
  size_t leaving_rows = 0;
  for (const auto& [db_index, frame] : impl.frames) {
    if (!std::binary_search(wanted.begin(), wanted.end(), db_index)) {
      leaving.push_back(db_index);
      leaving_rows += frame.num_rows;
    }
  }
  if (entering.empty() && leaving.empty()) return;

  const size_t total_after = impl.points.size() + entering_rows;
  const size_t removed_after = impl.num_removed + leaving_rows;
  const bool rebuild = !impl.index || (!options_.defer_rebuilds &&
                                       impl.Unbalanced(total_after, removed_after,
                                                       options_.rebuild_fraction));
  if (!rebuild) {
    for (int db_index : leaving) {
      const Frame& frame = impl.frames.at(db_index);
      for (int r = 0; r < frame.num_rows; ++r) impl.index->Remove(frame.first_id + r);
      impl.slot_db_index[frame.slot] = -1;
      impl.frames.erase(db_index);
    }
    impl.num_removed = removed_after;
    for (auto& [db_index, frame] : entering) {
      frame.slot = impl.TakeSlot(db_index);
      impl.AppendPoints(frame);
      if (frame.num_rows > 0) {
        impl.index->Add(frame.rows, static_cast<size_t>(frame.num_rows));
      }
      impl.frames.emplace(db_index, std::move(frame));
    }
    return;
  }
  for (int db_index : leaving) impl.frames.erase(db_index);
  entering.merge(impl.frames);
  impl.Build(std::move(entering), options_.num_trees, options_.leaf_size);
}

bool WindowMatcher::RebuildDue() const {
  const Impl& impl = *impl_;
  return impl.index != nullptr &&
         impl.Unbalanced(impl.points.size(), impl.num_removed, options_.rebuild_fraction);
}

void WindowMatcher::Rebuild() {
  Impl& impl = *impl_;
  std::map<int, Frame> window = std::move(impl.frames);
  impl.Build(std::move(window), options_.num_trees, options_.leaf_size);
}

std::vector<int> WindowMatcher::Window() const {
  std::vector<int> window;
  for (const auto& entry : impl_->frames) window.push_back(entry.first);
  return window;
}

int WindowMatcher::NumDescriptors() const {
  return static_cast<int>(impl_->points.size() - impl_->num_removed);
}

int WindowMatcher::NumRebuilds() const { return impl_->rebuilds; }

std::unordered_map<int, std::vector<WindowMatch>> WindowMatcher::Match(
    const FeatureDescriptors& query,
    int max_rows,
    double ratio,
    int checks,
    int num_threads) const {
  EPILOC_CHECK(ratio > 0 && ratio <= 1, "window matcher: ratio must be in (0, 1], got {}", ratio);
  EPILOC_CHECK(num_threads >= 1, "window matcher: num_threads must be >= 1, got {}", num_threads);
  EPILOC_CHECK(checks >= 1, "window matcher: checks must be >= 1, got {}", checks);
  const Impl& impl = *impl_;
  std::unordered_map<int, std::vector<WindowMatch>> matches;
  for (const auto& entry : impl.frames) matches[entry.first];
  int num_query = static_cast<int>(query.rows());
  if (max_rows >= 0) num_query = std::min(num_query, max_rows);
  const int num_points = NumDescriptors();
  if (!impl.index || num_query == 0 || num_points == 0) return matches;

  const int k = std::min(options_.max_neighbors, num_points);
  std::vector<float> query_rows = ToRootSift(query, num_query);
  const size_t num_results = static_cast<size_t>(num_query) * k;
  std::vector<size_t> ids(num_results, std::numeric_limits<size_t>::max());
  std::vector<float> distances(num_results, std::numeric_limits<float>::infinity());
  // Searching the (read-only) trees from several threads at once is safe.
  auto search = [&](int begin, int end) {
    if (begin >= end) return;
    const size_t offset = static_cast<size_t>(begin);
    impl.index->Search(query_rows.data() + offset * 128, static_cast<size_t>(end - begin), k,
                       checks, ids.data() + offset * k, distances.data() + offset * k);
  };
  const int threads = std::min(num_threads, std::max(1, num_query / 64));
  std::vector<std::thread> workers;
  for (int t = 1; t < threads; ++t) {
    workers.emplace_back(search, num_query * t / threads, num_query * (t + 1) / threads);
  }
  search(0, num_query / threads);
  for (std::thread& worker : workers) worker.join();

  // Per slot and database row, the closest query row that passed the ratio test.
  const size_t num_slots = impl.slot_db_index.size();
  std::vector<std::vector<WindowMatch>> best(num_slots);
  for (const auto& entry : impl.frames) best[entry.second.slot].resize(entry.second.num_rows);
  // The forest gives squared distances; the ratio test compares distances.
  const float ratio2 = static_cast<float>(ratio * ratio);
  struct Candidate {
    int slot;
    int position;  // of the frame's best among the k
    float second;  // squared distance of the frame's second best among the k
  };
  std::vector<Candidate> candidates;
  candidates.reserve(k);
  for (int i = 0; i < num_query; ++i) {
    const size_t* row_ids = ids.data() + static_cast<size_t>(i) * k;
    const float* row_distances = distances.data() + static_cast<size_t>(i) * k;
    candidates.clear();
    int found = 0;
    for (; found < k && row_ids[found] < impl.points.size(); ++found) {
      const int slot = impl.points[row_ids[found]].slot;
      auto it = std::find_if(candidates.begin(), candidates.end(),
                             [slot](const Candidate& c) { return c.slot == slot; });
      if (it == candidates.end()) {
        candidates.push_back({slot, found, std::numeric_limits<float>::infinity()});
      } else if (std::isinf(it->second)) {
        it->second = row_distances[found];
      }
    }
    // A frame's unseen second best is at least the k-th distance (infinite if fewer were found).
    const float bound = found == k ? row_distances[k - 1] : std::numeric_limits<float>::infinity();
    for (const Candidate& c : candidates) {
      const float d1 = row_distances[c.position];
      const float d2 = std::isinf(c.second) ? bound : c.second;
      if (!(d1 < ratio2 * d2)) continue;
      const int db_row = impl.points[row_ids[c.position]].row;
      WindowMatch& slot = best[c.slot][db_row];
      const float distance = std::sqrt(d1);
      if (slot.query_row < 0 || distance < slot.distance) slot = {i, db_row, distance};
    }
  }
  for (size_t s = 0; s < num_slots; ++s) {
    if (impl.slot_db_index[s] < 0) continue;
    std::vector<WindowMatch>& out = matches[impl.slot_db_index[s]];
    for (const WindowMatch& m : best[s]) {
      if (m.query_row >= 0) out.push_back(m);
    }
  }
  return matches;
}

}  // namespace epiloc
