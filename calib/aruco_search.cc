#include "calib/aruco_search.h"

#include <algorithm>

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

namespace topocal::calib {
namespace {

// Kalibr's corner squares touch the tags at their corners; at a few pixels per bit cell the blurred touching points
// threshold black and merge tag and squares into one contour, which aruco cannot read as a quad. Searching a 2x
// upsampled image keeps them apart: on 640 x 480 renders (55 px tags, blur 1 px, tilt 35-45 deg) aruco finds 12-17
// of 20 tags at full size and 20 of 20 upsampled. Images up to this size are upsampled (4x the pixels to search).
constexpr int kUpsampleUpToSidePx = 1280;
// aruco's adaptive threshold must be this much darker than the local mean: 7 (the default) lets the blurred
// touching points join tag and square; 10 separates them (same renders, upsampled: 16-20 -> 20 of 20 tags).
constexpr double kAdaptiveThresholdConstant = 10.0;
// Pixels per bit cell when aruco unwarps a candidate (default 4): 8 reads small, foreshortened cells better
// (same renders: 16 -> 20 of 20 tags at 45 deg).
constexpr int kPerspectiveRemovePixelPerCell = 8;

}  // namespace

void SearchArucoMarkers(const cv::Mat& gray, const cv::Ptr<cv::aruco::Dictionary>& dictionary, int border_bits,
                        std::vector<int>* ids, std::vector<std::vector<cv::Point2f>>* quads) {
  auto parameters = cv::aruco::DetectorParameters::create();
  parameters->markerBorderBits = border_bits;
  parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;  // topocal's saddle fit refines
  parameters->adaptiveThreshConstant = kAdaptiveThresholdConstant;
  parameters->perspectiveRemovePixelPerCell = kPerspectiveRemovePixelPerCell;
  cv::Mat search = gray;
  double scale = 1.0;
  if (std::max(gray.cols, gray.rows) <= kUpsampleUpToSidePx) {
    scale = 2.0;
    cv::resize(gray, search, cv::Size(), scale, scale, cv::INTER_LINEAR);
  }
  cv::aruco::detectMarkers(search, dictionary, *quads, *ids, parameters);
  // cv::resize maps pixel centres: x_search + 1/2 = scale (x + 1/2).
  const float s = static_cast<float>(scale);
  for (auto& quad : *quads) {
    for (auto& p : quad) p = (p + cv::Point2f(0.5f, 0.5f)) / s - cv::Point2f(0.5f, 0.5f);
  }
}

}  // namespace topocal::calib
