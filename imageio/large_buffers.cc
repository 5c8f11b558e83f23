#include "imageio/large_buffers.h"

#include <sys/mman.h>

#include <cstdint>
#include <opencv2/core/mat.hpp>

namespace topocal::imageio {
namespace {

// Buffers of at least kMinBytes (a huge page: a 3 MB half-resolution mask is then two faults, not 750) are mappings
// of their own, aligned to and rounded up to whole huge pages and advised MADV_HUGEPAGE before anything touches them:
// every page of the buffer can be huge. (Advising a buffer glibc maps would leave its unaligned ends, up to 4 MB, on
// 4 KB pages: ~500 faults of a 24 MB frame.) Smaller buffers, and buffers the caller provides, are OpenCV's own
// allocator's, which then also frees them (a buffer's UMatData names the allocator that made it). OpenCV has no such
// option, and glibc's (the glibc.malloc.hugetlb tunable) applies to the whole heap and only from the environment a
// process starts with.
class HugePageBuffers : public cv::MatAllocator {
 public:
  static constexpr std::size_t kMinBytes = std::size_t{2} << 20;
  static constexpr std::size_t kHugePage = std::size_t{2} << 20;

  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data, size_t* step, cv::AccessFlag flags,
                         cv::UMatUsageFlags usage) const override {
    if (data) return Std()->allocate(dims, sizes, type, data, step, flags, usage);
    // The continuous layout OpenCV's allocator gives (step[i]: the bytes of one index of dimension i).
    std::size_t total = CV_ELEM_SIZE(type);
    for (int i = dims - 1; i >= 0; --i) {
      if (step) step[i] = total;
      total *= static_cast<std::size_t>(sizes[i]);
    }
    void* mapped = total >= kMinBytes ? MapHuge(total) : nullptr;
    if (!mapped) return Std()->allocate(dims, sizes, type, data, step, flags, usage);
    auto* u = new cv::UMatData(this);
    u->data = u->origdata = static_cast<uchar*>(mapped);
    u->size = total;
    return u;
  }
  bool allocate(cv::UMatData* u, cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    return Std()->allocate(u, flags, usage);
  }
  void deallocate(cv::UMatData* u) const override {
    if (!u) return;
    if (u->currAllocator != this) {
      Std()->deallocate(u);
      return;
    }
    (void)munmap(u->origdata, RoundUp(u->size));
    delete u;
  }

 private:
  static const cv::MatAllocator* Std() { return cv::Mat::getStdAllocator(); }
  static std::size_t RoundUp(std::size_t bytes) { return (bytes + kHugePage - 1) & ~(kHugePage - 1); }

  // `bytes` rounded up to whole huge pages, at a huge-page boundary, advised; nullptr when the kernel refuses the
  // mapping (OpenCV's allocator then serves the buffer). Where the kernel has no THP the advice is ignored and the
  // buffer is the same on small pages.
  static void* MapHuge(std::size_t bytes) {
    const std::size_t length = RoundUp(bytes);
    void* raw = mmap(nullptr, length + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (raw == MAP_FAILED) return nullptr;
    const auto base = reinterpret_cast<std::uintptr_t>(raw);
    const auto aligned = (base + kHugePage - 1) & ~(std::uintptr_t{kHugePage} - 1);
    if (aligned > base) (void)munmap(raw, aligned - base);
    const std::size_t tail = base + length + kHugePage - (aligned + length);
    if (tail > 0) (void)munmap(reinterpret_cast<void*>(aligned + length), tail);
    (void)madvise(reinterpret_cast<void*>(aligned), length, MADV_HUGEPAGE);
    return reinterpret_cast<void*>(aligned);
  }
};

}  // namespace

void UseHugePagesForImageBuffers() {
  static HugePageBuffers buffers;  // lives as long as the process: Mats may be released at exit
  cv::Mat::setDefaultAllocator(&buffers);
}

}  // namespace topocal::imageio
