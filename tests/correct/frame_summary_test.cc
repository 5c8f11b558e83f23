// The frame summary the detector reads a frame's background from (one pass over the frame): the counts of its
// definition, and the threshold check from the band maxima.
#include "correct/frame_summary.h"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "correct/spot_detect.h"

namespace topocal::correct::detail {
namespace {

// Noise with flat stretches (runs of one value, as a dark or saturated region gives) and an odd width, so that the
// counting's whole-stretch shortcut and its tail both run.
cv::Mat Patchy(int rows, int cols, int type, int seed) {
  cv::Mat image(rows, cols, type);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::NORMAL, type == CV_8UC1 ? 40 : 1000, type == CV_8UC1 ? 3 : 60);
  image(cv::Rect(0, 0, cols / 2, rows / 3)).setTo(type == CV_8UC1 ? 255 : 4095);
  image(cv::Rect(cols / 3, rows / 2, cols / 2, rows / 4)).setTo(7);
  return image;
}

// The statistics of the summary's definition, counted plainly.
template <typename T>
void ExpectCountsOf(const cv::Mat& image, const FrameSummary& s) {
  std::vector<std::uint32_t> values(sizeof(T) == 1 ? 256 : 65536, 0), pairs(values.size(), 0);
  T top = 0;
  for (int r = 0; r < image.rows; ++r) {
    const T* p = image.ptr<T>(r);
    for (int c = 0; c < image.cols; ++c) {
      top = std::max(top, p[c]);
      if (r % 2 == 0 && c % 2 == 0) ++values[p[c]];
      if (r % 4 == 0 && c % 2 == 0 && c + 1 < image.cols) ++pairs[std::abs(int{p[c + 1]} - int{p[c]})];
    }
  }
  EXPECT_EQ(s.values(), values);
  EXPECT_EQ(s.differences(), pairs);
  EXPECT_TRUE(s.AnyAbove(top - 0.5));
  EXPECT_FALSE(s.AnyAbove(top));
}

TEST(FrameSummary, CountsTheSubsampleOfItsDefinition) {
  for (const int type : {CV_8UC1, CV_16UC1}) {
    SCOPED_TRACE(type);
    const cv::Mat image = Patchy(203, 157, type, 3);
    const FrameSummary s = FrameSummary::Of(image);
    if (type == CV_8UC1) {
      ExpectCountsOf<std::uint8_t>(image, s);
    } else {
      ExpectCountsOf<std::uint16_t>(image, s);
    }
  }
}

// A blank frame, flat or with read noise: nothing above the threshold, from the band maxima alone; a spot anywhere
// in it (here in the last, short band) is found.
TEST(FrameSummary, ABlankFrameHasNothingAboveItsThresholdAndOneSpotIsFound) {
  cv::Mat flat(1000, 1000, CV_16UC1, cv::Scalar(1000)), noisy(flat.size(), CV_16UC1);
  cv::RNG rng(7);
  rng.fill(noisy, cv::RNG::NORMAL, 1000, 60);
  for (const cv::Mat* blank : {&flat, &noisy}) {
    const SpotDetection d = DetectSpots(*blank);
    EXPECT_TRUE(d.spots.empty());
    EXPECT_GT(d.threshold_dn, 1000);
    cv::Mat one = blank->clone();
    cv::circle(one, {500, 990}, 3, cv::Scalar(30000), cv::FILLED);
    EXPECT_EQ(DetectSpots(one).spots.size(), 1u);
  }
}

}  // namespace
}  // namespace topocal::correct::detail
