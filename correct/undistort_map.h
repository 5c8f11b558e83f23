#pragma once
// Whole-image undistortion with cv::remap, the maps built from topocal's own distortion models (so Seidel works as
// well as Brown-Conrady, with its centre anywhere).
//
// cv::remap pulls: undistorted(u, v) = distorted(map(u, v)). The map therefore needs only the FORWARD model —
//   pixel (undistorted) -> detection plane mm -> model::Distort -> mm -> pixel (distorted)
// — evaluated once per output pixel, no per-pixel inverse. Output pixels beyond the fold of the distortion (where the
// forward map stops being one-to-one: for a radial model where d r_d / d r first falls to 0.01, just short of its
// zero) have no valid source; they are mapped to (-1, -1) and come out as the border value. The fold is computed
// for the radial part only: the tangential terms of a real lens (|p| ~ 1e-3) move it by far less than a pixel.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "model/distortion.h"
#include "model/topographer_camera.h"
#include "util/io.h"

namespace topocal::correct {

struct UndistortMap {
  cv::Mat map_x, map_y;  // CV_32FC1, size of the camera, distorted-image pixel coordinates per undistorted pixel
  int invalid_px = 0;    // output pixels beyond the fold (no source)
  // Detection-plane radius (mm, about the distortion centre) of the fold; +infinity when the model has none.
  double fold_radius_mm = 0;
};

// Builds the map for `camera`'s full sensor. Rows are built in parallel (cv::parallel_for_).
UndistortMap BuildUndistortMap(const model::Distortion& distortion, const model::TopographerCamera& camera);
// The same into `map`, reusing its buffers when they have the right size (rebuilding a map for a new calibration
// then costs no allocation: 96 MB of fresh pages for 4000 x 3000 cost about as much as computing the map).
void BuildUndistortMap(const model::Distortion& distortion, const model::TopographerCamera& camera, UndistortMap* map);

// The undistorted image (same size and type as `distorted`, which must match the camera's size). Pixels without a
// source are `border_value`. Throws util::InputError if the sizes differ.
cv::Mat UndistortImage(const cv::Mat& distorted, const UndistortMap& map, int interpolation = cv::INTER_LINEAR,
                       double border_value = 0.0);

// The same in one pass for a single image (the `undistort` verb): the map is built band by band, each band used for
// its rows of the output while it is still in cache and never stored whole; rows in parallel. Bit-identical to
// UndistortImage(distorted, BuildUndistortMap(distortion, camera)); *invalid_px (when given) = the map's invalid_px.
cv::Mat UndistortImage(const cv::Mat& distorted, const model::Distortion& distortion,
                       const model::TopographerCamera& camera, int* invalid_px = nullptr,
                       int interpolation = cv::INTER_LINEAR, double border_value = 0.0);

// The radius (mm on the detection plane, about the distortion centre) where the radial part of the model first
// stretches by less than 0.01 (d r_d / d r <= 0.01, just short of its fold) within `max_radius_mm`; +infinity if it
// never does out to there.
double FoldRadiusMm(const model::Distortion& distortion, double max_radius_mm);
// The same out to the farthest corner of `camera`'s sensor: the fold within the image (+infinity if it has none).
double SensorFoldRadiusMm(const model::Distortion& distortion, const model::TopographerCamera& camera);

}  // namespace topocal::correct
