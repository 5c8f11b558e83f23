#pragma once
// Synthetic ground truth: a calibration target seen through a camera with lens distortion, rendered by exact
// per-pixel inverse mapping.
//
// For every pixel, S ~ N*N sub-samples on a Fibonacci lattice (a rank-1 lattice: all S x- and y-offsets
// distinct, step 1/S, and evenly spread for edges of every orientation) shifted by a per-pixel random toroidal
// offset (Cranley-Patterson rotation), so each sub-sample is uniform over [0, 1)^2 (no bias) while the pattern
// stays stratified (low variance). A regular 4x4 grid would quantise an axis-aligned edge to 1/4 px per pixel and
// bias straight-on corners by up to 0.3 px.
// The optical blur is part of the sampling, as in a camera (blur before pixel integration): each uniform
// coordinate is mapped through the inverse CDF of "pixel box (1 px) convolved with the Gaussian blur (sigma)",
// per axis. Each sub-sample: image point -> undistorted normalised ray (CameraModel::PixelToNormalized exact on
// the pixel-corner lattice, then Newton steps on the forward model) -> intersection with the target plane ->
// black or white ink (TargetPattern). Pixels whose whole response support sees one grey are not sub-sampled, and
// the exact inverse is computed only near the paper's image (its forward projection, bounded cell by cell): beyond
// it every ray sees the background or has no inverse (past the fold of strong barrel distortion, where the inverse
// would iterate in vain), and the pixel is the background either way. Rows run in parallel, each pixel's offset
// drawn from one seeded stream at a position fixed by the pixel, so the image does not depend on the thread count.
// Seeded Gaussian noise (grey levels) is added and the result is rounded to 8 bits.
//
// Truth: the corner positions are CameraModel::Project(cam_from_target * corner) — exact, OpenCV pixel convention.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "calib/target.h"
#include "model/camera_model.h"

namespace topocal::calib {

// point_in_cam = rotation * point_in_target + translation_mm
struct CamFromTarget {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();
};

// From a rotation vector (axis * angle, degrees) and a translation (mm).
CamFromTarget PoseFromRotationVector(const Eigen::Vector3d& rotation_vector_deg, const Eigen::Vector3d& translation_mm);
// The pattern's centre on the optical axis at `distance_mm`, the target turned by tilt_x about its x axis, then
// tilt_y about its y axis, then roll about the optical axis (degrees), then shifted by (shift_x, shift_y) mm in
// the camera frame.
CamFromTarget PoseFacingTarget(const TargetDescription& target, double distance_mm, double tilt_x_deg = 0,
                               double tilt_y_deg = 0, double roll_deg = 0, double shift_x_mm = 0,
                               double shift_y_mm = 0);

struct RenderOptions {
  int supersampling = 16;        // N: the Fibonacci number nearest N*N of sub-samples per pixel near edges
  double blur_sigma_px = 1.0;    // optical Gaussian blur (before pixel integration), px; 0 = none
  double noise_grey = 0.0;       // standard deviation of additive Gaussian noise, grey levels
  uint32_t seed = 1;             // sub-sample offsets and noise
  double black_grey = 30.0;      // ink
  double white_grey = 220.0;     // paper
  double background_grey = 110.0;  // beyond the paper and where rays miss the plane
  int jobs = 0;                  // threads (0: every core this process may use); the image does not depend on it

  bool IsValid(std::string* why) const;
};

struct CornerTruth {
  int id = 0;
  Eigen::Vector2d image_px;  // OpenCV pixel convention
};

struct RenderedView {
  cv::Mat image;                     // CV_8UC1, camera.height_px x camera.width_px
  cv::Mat irradiance;                // CV_32FC1: the same before noise and rounding
  std::vector<CornerTruth> corners;  // corners inside the image (and in front of the camera), ascending id
};

// The rendered view's ground truth as `render-target --truth` writes it: "id,x_px,y_px", one row per corner in
// view, ascending id, 9 decimals (OpenCV pixel convention). Read back by the detection tests.
std::string CornerTruthCsv(const RenderedView& view);

// Seeded Gaussian noise (grey levels) on a float image, rounded and clamped to 8 bits: the last step of
// RenderTarget, exposed so that one rendering can be seen at several noise levels.
cv::Mat AddSensorNoise(const cv::Mat& irradiance, double noise_grey, uint32_t seed);

// nullopt when the options or the camera are invalid (why says which).
std::optional<RenderedView> RenderTarget(const TargetDescription& target, const model::CameraModel& camera,
                                         const CamFromTarget& pose, const RenderOptions& options,
                                         std::string* why = nullptr);

}  // namespace topocal::calib
