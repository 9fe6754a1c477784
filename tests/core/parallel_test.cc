#include "epiloc/core/parallel.h"

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

#include <gtest/gtest.h>

namespace epiloc {
namespace {

TEST(ParallelFor, RunsEveryIndexOnceOnSeveralThreads) {
  for (const int threads : {0, 1, 2, 8}) {
    std::mutex mutex;
    std::multiset<int64_t> seen;
    std::set<std::thread::id> ids;
    ParallelFor(1000, threads, [&](int64_t i) {
      std::lock_guard<std::mutex> lock(mutex);
      seen.insert(i);
      ids.insert(std::this_thread::get_id());
    });
    ASSERT_EQ(seen.size(), 1000u) << threads;
    for (int64_t i = 0; i < 1000; ++i) EXPECT_EQ(seen.count(i), 1u);
    EXPECT_LE(static_cast<int>(ids.size()), std::max(1, threads));
  }
  int calls = 0;
  ParallelFor(0, 4, [&](int64_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

TEST(ParallelFor, RethrowsTheFirstErrorAfterAllThreadsStopped) {
  // One thread: the tasks after the failing one are skipped.
  std::atomic<int> started{0};
  EXPECT_THROW(ParallelFor(10000, 1,
                           [&](int64_t i) {
                             ++started;
                             if (i == 10) throw std::runtime_error("task 10 failed");
                           }),
               std::runtime_error);
  EXPECT_EQ(started.load(), 11);
  // Two threads: how many tasks the other thread finished before the failure depends on the
  // scheduler (all of them, on a busy machine); but when ParallelFor returns, no task runs on.
  started = 0;
  EXPECT_THROW(ParallelFor(10000, 2,
                           [&](int64_t i) {
                             ++started;
                             if (i == 10) throw std::runtime_error("task 10 failed");
                           }),
               std::runtime_error);
  const int at_return = started.load();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(started.load(), at_return);
}

}  // namespace
}  // namespace epiloc
