#pragma once
// Internal to correct/ (spot_detect.cc): the image's background level and noise from robust statistics of a
// subsample (docs/spot-noise.md, "The noise model measured"). Not part of the library's interface.
#include <vector>

#include <opencv2/core.hpp>

#include "correct/frame_summary.h"

namespace topocal::correct::detail {

struct BackgroundStats {
  double median = 0;  // DN
  // 1.4826 MAD of the pixel values (DN): the read noise where most of the frame is background. For an integer
  // image it is the MAD of the values spread over their rounding interval, so it resolves fractions of a DN and
  // measures about sqrt(read^2 + 1/12) — the read noise and the quantisation together.
  double sigma = 0;
  double bright = 0;  // 99.99th percentile: the spots' level
  // The noise from differences of horizontally adjacent pixels (1.4826 MAD / sqrt 2), likewise spread: blind to a
  // background that changes smoothly (a lid's skin over part of the frame), which widens `sigma` by the difference
  // of the levels.
  double sigma_diff = 0;
};

// Every 2nd pixel of every 2nd row for the level (a quarter of the image: enough samples, a quarter of the cost),
// disjoint adjacent pairs on every 4th row for the differences. An integer frame's from the histograms of its
// FrameSummary (one pass, no sort).
BackgroundStats BackgroundOf(const FrameSummary& summary);
// The same samples of a float image (CV_32FC1), through nth_element.
BackgroundStats MeasureBackground(const cv::Mat& image);

// The read noise (DN, quantisation excluded) of the background left where the spots' light cannot reach: the
// pixels of the background's subsample (BackgroundOf) outside every rectangle of `occupied` (image coordinates)
// grown by half its own size and at least `margin_px` (a spot's tail reaches a few PSF widths past its thresholded
// extent). Where
// the spots cover most of the frame the histogram of the whole frame is widened by their tails (a 1000 x 1000 crop
// of the pattern reads 8-10 % high); the whole frame's when fewer than 10,000 pixels are left. Maximum likelihood
// of the histogram's core as rounded Gaussian samples; for a float image `whole_frame` (its sigma) is returned.
double ReadNoiseAwayFrom(const cv::Mat& image, const std::vector<cv::Rect>& occupied, int margin_px,
                         double whole_frame);

// The quantisation an integer image adds to every pixel: 1/12 DN^2 (uniform rounding error); 0 for float images.
double QuantisationVariance(const cv::Mat& image);

}  // namespace topocal::correct::detail
