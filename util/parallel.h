#pragma once
// The project's one way to run independent work items on several cores.
//
//   std::vector<Result> out(items.size());
//   util::ParallelFor(items.size(), jobs, [&](size_t i) { out[i] = Work(items[i]); });
//
// Each index runs exactly once on one of up to `jobs` threads (0: every core this process may use). Callers write
// results by index only, so the outcome does not depend on the thread count or the scheduling. If fn throws, the
// indices not yet started are skipped and the first exception (in time) is rethrown once every thread has stopped.
// Written on std::thread rather than cv::parallel_for_ because the thread count is per call (OpenCV's is global)
// and exceptions must cross back to the caller.
#include <cstddef>
#include <functional>
#include "util/io.h"

namespace topocal::util {

// Cores this process may run on (its CPU affinity, as a container or `taskset` limits it), at least 1.
int AvailableCores();

// `jobs` < 0 is a programming error (util::InputError); 0 means AvailableCores().
void ParallelFor(size_t n, int jobs, const std::function<void(size_t)>& fn);

}  // namespace topocal::util
