// A parallel loop over an index range: the one thread pool pattern of the project (feature
// extraction, pair evaluation, triangulation, map building and anchoring use it).
#pragma once

#include <cstdint>
#include <functional>

namespace epiloc {

// Runs task(i) for i in [0, n) on up to `num_threads` threads (the calling thread included; at
// most n; < 1 counts as 1), handing out indices in increasing order to whichever thread is free.
// The first exception a task throws is rethrown after all threads have stopped; the indices not
// yet started are then skipped.
void ParallelFor(int64_t n, int num_threads, const std::function<void(int64_t)>& task);

}  // namespace epiloc
