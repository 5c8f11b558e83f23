#pragma once
// A raw spot image to reconstruction input: detect and index the spots (correct/), convert to detection-plane mm
// through the camera, and undistort them with a calibrated distortion when one is given.
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "model/config.h"
#include "model/distortion.h"
#include "model/topographer_camera.h"
#include "topo/reconstruction.h"

namespace topocal::pipeline {

// A detected and identified spot as the camera saw it (distorted), on the detection plane.
struct MeasuredImageSpot {
  model::SpotId id;
  Eigen::Vector2d distorted_mm;
};

struct SpotMeasurement {
  std::vector<MeasuredImageSpot> detected;  // every identified spot, distorted, by id
  std::vector<topo::MeasuredSpot> spots;  // identified (and undistorted, if a distortion was given), by id
  int indexed = 0;
  int unassigned = 0;                      // detections without identity (glints)
  int missing = 0;                         // designed spots not found
  int undistort_failures = 0;              // identified spots outside the calibration's invertible domain
};

// The detected (distorted) spots undistorted with `distortion`. Spots outside its invertible domain are left out;
// *failures (if given) counts them.
std::vector<topo::MeasuredSpot> UndistortSpots(const std::vector<MeasuredImageSpot>& detected,
                                               const model::Distortion& distortion, int* failures = nullptr);

// Throws std::runtime_error (one line) when detection or indexing fails; std::invalid_argument for an image type
// the detector cannot use.
SpotMeasurement MeasureSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                             const model::IdealImageParams& ideal, const std::optional<model::Distortion>& distortion);

}  // namespace topocal::pipeline
