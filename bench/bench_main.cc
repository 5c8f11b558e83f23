// The benchmarks' main: Google Benchmark's, after the allocator set-up the topocal CLI does (util/allocator.h), so
// that a benchmark measures what the CLI runs.
#include <benchmark/benchmark.h>

#include "util/allocator.h"

int main(int argc, char** argv) {
  topocal::util::KeepAnalysisBuffersInTheHeap();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
