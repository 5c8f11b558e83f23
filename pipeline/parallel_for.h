#pragma once
// The project's one worker pool for independent, equally shaped tasks (harness cases, Monte Carlo draws): fn(i) for
// every i in [0, count) on up to `jobs` threads (the caller's thread is one of them), each thread taking the next
// index from a shared counter. Results stay independent of `jobs` as long as fn(i) writes only slot i and draws its
// random numbers from a seed of its own (e.g. std::seed_seq{seed, i}).
//
// Written on std::thread rather than cv::parallel_for_: the callers sit in pipeline/, whose tasks (reconstruction,
// Ceres fits) have nothing to do with OpenCV, and an explicit `jobs` lets a caller that already runs in parallel (a
// batch of units) ask for exactly one thread. Threads are started per call: a call runs for milliseconds to
// minutes, so the ~50 us of starting two threads is not worth a persistent pool.
#include <cstddef>
#include <functional>

namespace topocal::pipeline {

// jobs <= 0: std::thread::hardware_concurrency(). Never more threads than tasks. The first exception a task throws
// is rethrown here after every thread has finished (the remaining tasks still run).
void ParallelFor(std::size_t count, int jobs, const std::function<void(std::size_t)>& fn);

// The thread count ParallelFor uses for `jobs` and `count`.
int ParallelJobs(std::size_t count, int jobs);

}  // namespace topocal::pipeline
