#pragma once
// The default of every --jobs: the cores this process may run on (its CPU affinity, which containers, taskset and
// Slurm's cgroups restrict), not the machine's total that std::thread::hardware_concurrency reports.
#include <sched.h>

#include <algorithm>
#include <thread>

namespace topocal::tools {

inline int CoresAvailable() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) return std::max(1, CPU_COUNT(&set));
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

}  // namespace topocal::tools
