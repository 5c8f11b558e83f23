#pragma once
// Checkerboard corners: OpenCV finds the board, topocal orders and refines the corners.
//
// Ordering: ids as in calib/target.h (row-major, corner 0 with the black outer square diagonally before it). OpenCV
// returns the corners row-major but in any of the board's symmetric orientations; the detector restores the
// target's handedness (x then y turn clockwise in the image for a board seen from the front) and, when
// targetCols + targetRows is odd, the 180-degree orientation from the colour of the squares around corner 0. For
// an even sum the 180-degree ambiguity is inherent; corner 0 is then the one nearer the image's top-left.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "calib/detect.h"
#include "calib/target.h"

namespace topocal::calib {

// Corners of the whole board, index = corner id; nullopt (with `why`) when the board is not found or a corner
// cannot be refined. `gray` is CV_8UC1.
std::optional<std::vector<Eigen::Vector2d>> DetectCheckerboardCorners(const cv::Mat& gray,
                                                                      const CheckerboardLayout& board,
                                                                      const DetectionOptions& options,
                                                                      std::string* why);

}  // namespace topocal::calib
