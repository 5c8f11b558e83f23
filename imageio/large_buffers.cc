#include "imageio/large_buffers.h"

#include <sys/mman.h>

#include <cstdint>
#include <opencv2/core/mat.hpp>

namespace topocal::imageio {
namespace {

// OpenCV's own allocator does the work (its buffers, alignment and release: a buffer's UMatData names the standard
// allocator, which frees it); this only advises a large buffer before anything touches its pages. OpenCV has no
// such option and glibc's (the glibc.malloc.hugetlb tunable) applies to the whole heap and only from the
// environment a process starts with.
class HugePageAdvice : public cv::MatAllocator {
 public:
  static constexpr std::size_t kMinBytes = std::size_t{4} << 20;
  static constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;

  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data, size_t* step, cv::AccessFlag flags,
                         cv::UMatUsageFlags usage) const override {
    cv::UMatData* u = Std()->allocate(dims, sizes, type, data, step, flags, usage);
    if (!data && u && u->size >= kMinBytes) {
      // The whole huge pages inside the buffer; the partial ones at its ends stay on 4 KB pages.
      const auto begin = (reinterpret_cast<std::uintptr_t>(u->data) + kHugePage - 1) & ~(kHugePage - 1);
      const auto end = (reinterpret_cast<std::uintptr_t>(u->data) + u->size) & ~(kHugePage - 1);
      // Advice only: where the kernel has no THP, or refuses, the buffer is the same on small pages.
      if (end > begin) (void)madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
    }
    return u;
  }
  bool allocate(cv::UMatData* u, cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    return Std()->allocate(u, flags, usage);
  }
  void deallocate(cv::UMatData* u) const override { Std()->deallocate(u); }

 private:
  static const cv::MatAllocator* Std() { return cv::Mat::getStdAllocator(); }
};

}  // namespace

void UseHugePagesForImageBuffers() {
  static HugePageAdvice advice;  // lives as long as the process: Mats may be released at exit
  cv::Mat::setDefaultAllocator(&advice);
}

}  // namespace topocal::imageio
