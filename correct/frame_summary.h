#pragma once
// What the spot detector reads of a whole frame before it looks at any spot (spot_detect.h, steps 1-2): the
// histogram of the background subsample (every 2nd pixel of every 2nd row), the histogram of the differences of
// disjoint adjacent pixel pairs on every 4th row, and the maximum of each band of 64 rows (is anything above the
// threshold?). Built in one pass, row by row in order, so that it can ride on the decoder while each row is still
// in cache (imageio::RowSink; pipeline::ReadSpotImage): a frame without a spot is then read from memory once, by the
// decoder, instead of three times.
//
//   correct::FrameSummary summary;
//   const cv::Mat image = imageio::ReadImage(path, Channels::kAsStored,
//                                            {}, [&](int y, const cv::Mat& row) { summary.AddRow(y, row); });
//   const auto detection = correct::DetectSpots(correct::Frame(image, summary));
//
// Only one-channel 8- and 16-bit frames are summarised; DetectSpots measures any other itself.
#include <cstdint>
#include <memory>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace topocal::correct {

class FrameSummary {
 public:
  static constexpr int kBandRows = 64;

  // The summary of a whole decoded frame.
  static FrameSummary Of(const cv::Mat& image);

  // Row y (1 x width, the frame's type) of a frame read top to bottom; y = 0 starts a new frame. A row out of order
  // or of a type that is not summarised leaves the summary incomplete (Summarises is then false).
  void AddRow(int y, const cv::Mat& row);

  // Whether this is the complete summary of a frame of `image`'s size and type.
  bool Summarises(const cv::Mat& image) const noexcept;

  // Whether any pixel is above `threshold_dn` (every pixel of an integer frame is above a negative one).
  bool AnyAbove(double threshold_dn) const noexcept;

  const std::vector<std::uint32_t>& values() const noexcept { return values_; }            // by value, DN
  const std::vector<std::uint32_t>& differences() const noexcept { return differences_; }  // by |difference|

 private:
  int rows_ = 0, cols_ = 0, type_ = -1, next_row_ = 0;
  bool broken_ = true;
  std::vector<std::uint32_t> values_, differences_;
  std::vector<std::uint16_t> band_max_;
};

// A frame and, when the decoder measured it, its summary: DetectSpots takes the background from a summary that
// Summarises the image and measures it otherwise. Any cv::Mat is a frame without a summary. The summary is that of
// the pixels as decoded: a caller that changes the image afterwards drops it (Frame(image)).
struct Frame {
  Frame(cv::Mat image) : image(std::move(image)) {}  // NOLINT(google-explicit-constructor): every image is a frame
  Frame(cv::Mat image, FrameSummary summary)
      : image(std::move(image)), summary(std::make_shared<const FrameSummary>(std::move(summary))) {}
  cv::Mat image;
  std::shared_ptr<const FrameSummary> summary;
};

}  // namespace topocal::correct
