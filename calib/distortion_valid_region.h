#pragma once
// Where a calibrated camera's distortion model can be trusted: the disc about the principal point inside which the
// model (calib/camera.h, with its distortion centre) is monotonic and therefore invertible. A strongly negative k1
// (e.g. -6.2) makes the distorted radius turn back (r_d(r) has a maximum): beyond it two directions land on one pixel,
// the inverse has no unique answer and cv::undistort paints mirrored copies of the centre ("ghost boards").
//
// Computed along 360 undistorted rays from the distortion centre: on each ray, the first point where the Jacobian
// of normalised -> pixel stops being positive definite in orientation (det J <= 0, the fold), found by marching in
// steps of at most ~1 px and bisection to 1e-3 px. radius_px is the smallest pixel distance from the principal point
// to a fold, i.e. the largest circle about (cx, cy) inside the valid region. Where no ray folds out to twice the
// sensor's half-diagonal the model is valid over all of it and radius_px is that search limit (a lower bound).
// Decision and evidence: docs/exchange.md ("Valid region").
#include "model/camera_model.h"

namespace topocal::calib {

struct DistortionValidRegion {
  double radius_px = 0;        // about (cx, cy): the distortion model is monotonic and invertible inside
  bool covers_sensor = false;  // every pixel of the width x height sensor lies inside radius_px
};

DistortionValidRegion ValidRegionOf(const model::CameraModel& camera);

// Whether pixel `px` (OpenCV convention) lies inside the region of `camera`.
bool InsideValidRegion(const DistortionValidRegion& region, const model::CameraModel& camera,
                       const Eigen::Vector2d& px);

// Distance (px) from the principal point to the sensor's farthest pixel centre.
double FarthestSensorPixelPx(const model::CameraModel& camera);

}  // namespace topocal::calib
