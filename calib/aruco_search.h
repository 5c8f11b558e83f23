#pragma once
// The marker search shared by the aruco-based detectors (Kalibr AprilGrids, ChArUco): cv::aruco::detectMarkers with
// the settings topocal measured for small, blurred, tilted markers, on a 2x upsampled image when the image is small.
// Corners come back in the input image's pixels (OpenCV convention), aruco's order, unrefined.
#include <vector>

#include <opencv2/aruco/dictionary.hpp>
#include <opencv2/core/mat.hpp>

namespace topocal::calib {

// Throws cv::Exception (the callers turn it into a message).
void SearchArucoMarkers(const cv::Mat& gray, const cv::Ptr<cv::aruco::Dictionary>& dictionary, int border_bits,
                        std::vector<int>* ids, std::vector<std::vector<cv::Point2f>>* quads);

}  // namespace topocal::calib
