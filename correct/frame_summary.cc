#include "correct/frame_summary.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace topocal::correct::detail {
namespace {

// Sixteen pixels from p: whether all equal p[0]. On a flat stretch (a dark or saturated frame, a blank one) every
// sample falls in the same bin, and each increment of it would wait for the store of the one before; such a stretch
// is counted at once. SSE2 (every x86-64) compares the sixteen at once; GCC does not vectorise the scalar loop.
template <typename T>
bool Flat16(const T* p) noexcept {
#if defined(__SSE2__)
  if constexpr (sizeof(T) == 1) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p));
    return _mm_movemask_epi8(_mm_cmpeq_epi8(v, _mm_set1_epi8(static_cast<char>(p[0])))) == 0xFFFF;
  } else {
    const __m128i first = _mm_set1_epi16(static_cast<short>(p[0]));
    const __m128i lo = _mm_cmpeq_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)), first);
    const __m128i hi = _mm_cmpeq_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 8)), first);
    return _mm_movemask_epi8(_mm_and_si128(lo, hi)) == 0xFFFF;
  }
#else
  unsigned diff = 0;
  for (int i = 1; i < 16; ++i) diff |= static_cast<unsigned>(p[i] ^ p[0]);
  return diff == 0;
#endif
}

template <typename T>
T RowMax(const T* p, int cols) noexcept {
  T top = 0;
  for (int c = 0; c < cols; ++c) top = std::max(top, p[c]);
  return top;
}

// Every 2nd pixel of the row into `values`; with `pairs`, |p[c + 1] - p[c]| of the pairs (c even) into `pairs`.
// Returns the row's maximum.
template <typename T>
T CountRow(const T* p, int cols, std::uint32_t* values, std::uint32_t* pairs) noexcept {
  const T top = RowMax(p, cols);
  int c = 0;
  for (; c + 16 <= cols; c += 16) {
    if (Flat16(p + c)) {
      values[p[c]] += 8;
      if (pairs) pairs[0] += 8;
      continue;
    }
    for (int k = c; k < c + 16; k += 2) {
      ++values[p[k]];
      if (pairs) ++pairs[std::abs(static_cast<int>(p[k + 1]) - static_cast<int>(p[k]))];
    }
  }
  for (; c < cols; c += 2) {
    ++values[p[c]];
    if (pairs && c + 1 < cols) ++pairs[std::abs(static_cast<int>(p[c + 1]) - static_cast<int>(p[c]))];
  }
  return top;
}

}  // namespace

FrameSummary FrameSummary::Of(const cv::Mat& image) {
  CV_Assert(image.type() == CV_8UC1 || image.type() == CV_16UC1);
  FrameSummary s;
  s.values_.assign(image.type() == CV_8UC1 ? 256 : 65536, 0);
  s.differences_.assign(s.values_.size(), 0);
  s.empty_ = image.empty();
  for (int y = 0; y < image.rows; ++y) {
    if (image.type() == CV_8UC1) {
      s.AddRow(y, image.ptr<std::uint8_t>(y), image.cols);
    } else {
      s.AddRow(y, image.ptr<std::uint16_t>(y), image.cols);
    }
  }
  return s;
}

template <typename T>
void FrameSummary::AddRow(int y, const T* row, int cols) {
  std::uint32_t* pairs = y % 4 == 0 ? differences_.data() : nullptr;
  const T top = y % 2 == 0 ? CountRow(row, cols, values_.data(), pairs) : RowMax(row, cols);
  if (y % kBandRows == 0) band_max_.push_back(0);
  band_max_.back() = std::max<std::uint16_t>(band_max_.back(), top);
}

bool FrameSummary::AnyAbove(double threshold_dn) const noexcept {
  if (threshold_dn < 0) return !empty_;
  const double limit = std::floor(threshold_dn);
  return std::any_of(band_max_.begin(), band_max_.end(), [limit](std::uint16_t m) { return m > limit; });
}

}  // namespace topocal::correct::detail
