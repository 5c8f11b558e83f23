#include "util/allocator.h"

#include <malloc.h>

namespace topocal::util {

void KeepAnalysisBuffersInTheHeap() {
  // mallopt is glibc's documented interface for both (mallopt(3)); setting either disables the dynamic adjustment.
  mallopt(M_MMAP_THRESHOLD, 4 << 20);
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
}

}  // namespace topocal::util
