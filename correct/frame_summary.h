#pragma once
// Internal to correct/ (spot_detect.cc): what the spot detector reads of a whole frame before it looks at any spot
// (spot_detect.h, steps 1-2): the histogram of the background subsample (every 2nd pixel of every 2nd row), the
// histogram of the differences of disjoint adjacent pixel pairs on every 4th row, and the maximum of each band of 64
// rows (is anything above the threshold?). One pass over the frame, row by row, where the histograms and the
// threshold check were two: on a blank frame, the whole of the detection. Only one-channel 8- and 16-bit frames are
// summarised; a float frame is measured from its pixels (background_stats.h).
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace topocal::correct::detail {

class FrameSummary {
 public:
  static constexpr int kBandRows = 64;

  // The summary of a whole frame: `image` CV_8UC1 or CV_16UC1 (DetectSpots has checked it).
  static FrameSummary Of(const cv::Mat& image);

  // Whether any pixel is above `threshold_dn` (every pixel of an integer frame is above a negative one).
  bool AnyAbove(double threshold_dn) const noexcept;

  const std::vector<std::uint32_t>& values() const noexcept { return values_; }            // by value, DN
  const std::vector<std::uint32_t>& differences() const noexcept { return differences_; }  // by |difference|

 private:
  template <typename T>
  void AddRow(int y, const T* row, int cols);

  bool empty_ = true;
  std::vector<std::uint32_t> values_, differences_;
  std::vector<std::uint16_t> band_max_;
};

}  // namespace topocal::correct::detail
