#pragma once
// ChArUco boards (calib/target.h): OpenCV 4.6 contrib aruco finds the markers and interpolates the chessboard
// corners between them (cv::aruco::interpolateCornersCharuco: a corner needs two neighbouring markers), so a board
// cut by the frame or partly occluded gives its visible corners with their identities. topocal then refines every
// corner with the saddle fit (calib/corner_refinement.h): a ChArUco X-junction is point-symmetric within the white
// margin between the markers and the square edges, so the window is sigma = margin / 4 (weights at the margin below
// exp(-8)), clamped to [1, 3] px, smaller near the image edge; a corner that cannot be refined is left out with its
// reason.
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "calib/detect.h"
#include "calib/target.h"

namespace topocal::calib {

struct CharucoDetections {
  std::vector<std::pair<int, Eigen::Vector2d>> corners;  // (corner id, OpenCV pixel), ascending id
  int markers_detected = 0;
  int markers_rejected = 0;
  std::vector<std::string> reasons;
  std::string message;
};

// `gray` is CV_8UC1. Never throws for image content.
CharucoDetections DetectCharuco(const cv::Mat& gray, const CharucoLayout& board, const DetectionOptions& options);

}  // namespace topocal::calib
