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

struct CheckerboardCorners {
  std::vector<Eigen::Vector2d> corners_px;  // index = corner id
  std::vector<bool> found;                  // false: this corner could not be refined and is left out
  std::vector<std::string> reasons;         // one line per left-out corner
  int beyond_frame = 0;                     // a board cut by the frame: corners not in the image (found = false)
};

// Finding the board: cv::findChessboardCorners (the classic detector, fast) first, cv::findChessboardCornersSB only
// when it fails; then the saddle fit. A corner whose window would leave the image is refined with the largest
// window that fits (down to kMinEdgeWindowSigmaPx), else left out with its reason; the board is never dropped for
// it. nullopt (with `why`, including a hint when the image shows a board one corner smaller in both directions, i.e.
// squares were counted instead of inner corners) when the board is not found. `gray` is CV_8UC1.
// A board cut by the frame: the corners in the image are used when their place on the board is the only
// one consistent with the frame, the square colours and the handedness (up to the board's own symmetry); the
// others are reported in `beyond_frame`. Ambiguous placements are refused with their count (see the .cc).
std::optional<CheckerboardCorners> DetectCheckerboardCorners(const cv::Mat& gray, const CheckerboardLayout& board,
                                                             const DetectionOptions& options, std::string* why);

}  // namespace topocal::calib
