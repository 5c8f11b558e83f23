#pragma once
// OpenCV's view of a pixel camera: the camera matrix K and the distortion coefficients (1 x the lens model's count,
// OpenCV's order), as OpenCV's files and calls take them. The one place topocal's CameraModel becomes K + distCoeffs.
#include <opencv2/core/mat.hpp>
#include <opencv2/core/matx.hpp>

#include "model/camera_model.h"
#include "model/lens_model.h"

namespace topocal::calib {

inline cv::Matx33d OpenCvCameraMatrix(const model::CameraModel& c) {
  return {c.fx_px, 0, c.cx_px, 0, c.fy_px, c.cy_px, 0, 0, 1};
}

inline cv::Mat OpenCvDistCoeffs(const model::CameraModel& c) {
  cv::Mat row(1, model::LensParameterCount(c.lens), CV_64F);
  for (int i = 0; i < row.cols; ++i) row.at<double>(i) = c.dist[static_cast<size_t>(i)];
  return row;
}

}  // namespace topocal::calib
