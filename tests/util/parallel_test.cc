#include "util/parallel.h"
#include "util/io.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

namespace topocal::util {
namespace {

// Every index exactly once, whatever the thread count (0 = every core, more threads than items, one thread).
TEST(ParallelFor, RunsEveryIndexOnceWhateverTheThreadCount) {
  for (const int jobs : {0, 1, 2, 7, 64}) {
    SCOPED_TRACE(jobs);
    std::vector<std::atomic<int>> hits(37);
    util::ParallelFor(hits.size(), jobs, [&](size_t i) { ++hits[i]; });
    for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
  }
  int calls = 0;
  util::ParallelFor(0, 4, [&](size_t) { ++calls; });
  EXPECT_EQ(calls, 0);
  EXPECT_GE(util::AvailableCores(), 1);
  EXPECT_THROW(util::ParallelFor(3, -1, [](size_t) {}), util::InputError);
}

// An exception in one item reaches the caller after every thread has stopped; later items are not started.
TEST(ParallelFor, TheFirstExceptionReachesTheCaller) {
  std::atomic<int> started{0};
  try {
    // The other items take 1 ms each: the second thread would need a second for all of them, far longer than the
    // failing one takes to stop the loop even on a loaded machine (with a bare yield, a loaded machine can let the
    // second thread start all 1000 before the stop lands).
    util::ParallelFor(1000, 2, [&](size_t i) {
      ++started;
      if (i == 3) throw std::runtime_error("item 3 failed");
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "item 3 failed");
  }
  EXPECT_LT(started.load(), 1000);
}

}  // namespace
}  // namespace topocal::util
