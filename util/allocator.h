#pragma once

namespace topocal::util {

// glibc gives a freed block above its trim threshold back to the kernel and serves a request above its mmap
// threshold with a fresh mapping; both thresholds start at 128 KB and only rise when a large block is freed. An
// analysis allocates and frees the same buffers of a few hundred KB (the power maps' 288 KB, the slope fit's
// tables) many times a second, and on the 2-core VM every fresh page costs 12-20 us: with the defaults the paper
// sweep spent ~15 ms of its ~40 ms in page faults (docs/performance.md). This keeps blocks below 4 MB in
// the heap and the heap's top below 64 MB untrimmed; the results do not change, only where memory comes from.
// A library never changes the allocator of the program that links it: programs call this (the topocal CLI in
// tools/cli_app.cc, the benchmarks in bench/bench_main.cc), before their first allocation of that kind.
void KeepAnalysisBuffersInTheHeap();

}  // namespace topocal::util
