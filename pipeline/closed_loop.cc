#include "pipeline/closed_loop.h"

#include <fmt/format.h>

#include <stdexcept>

#include "calib/calibrate.h"
#include "calib/detect.h"
#include "calib/render_target.h"
#include "calib/target.h"
#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "model/camera_model.h"
#include "model/null_screen.h"
#include "pipeline/detection_plane.h"
#include "pipeline/measure_spots.h"

namespace topocal::pipeline {
namespace {

model::TopographerCamera RegionOfInterest(const ClosedLoopOptions& o) {
  model::TopographerCamera roi = o.camera;
  roi.width_px = roi.height_px = 2 * o.roi_half_px;
  roi.principal_point_px = Eigen::Vector2d(o.roi_half_px - 0.5, o.roi_half_px - 0.5);
  return roi;
}

model::CameraModel CameraThrough(const model::TopographerCamera& roi, const model::Config& config, double sigma) {
  model::CameraModel cam;
  cam.width_px = roi.width_px;
  cam.height_px = roi.height_px;
  cam.fx_px = cam.fy_px = roi.FocalPx();
  cam.cx_px = roi.principal_point_px.x();
  cam.cy_px = roi.principal_point_px.y();
  // OpenCV's normalised coordinates are x1 / a on the detection plane (docs/camera-conventions.md), so the Seidel
  // distortion is Brown's k1 = sigma a^2 / M_T^3 about the principal point.
  cam.dist = {model::SeidelSigmaToBrownK1(sigma, config.distortion.magnification, roi.a_mm)};
  return cam;
}

CalibrationOutcome Calibrate(const model::Config& config, const model::TopographerCamera& roi,
                             const model::CameraModel& truth_camera, const ClosedLoopOptions& o, double sigma) {
  const auto target = calib::ParseTargetDescription(
      fmt::format("target_type: checkerboard\ntargetCols: {}\ntargetRows: {}\nrowSpacingMeters: {}\n"
                  "colSpacingMeters: {}\n",
                  o.target_cols, o.target_rows, o.target_square_mm * 1e-3, o.target_square_mm * 1e-3),
      "closed-loop target");
  calib::RenderOptions render;
  render.blur_sigma_px = o.target_blur_px;
  render.supersampling = o.target_supersampling;
  render.noise_grey = o.target_noise_grey;
  render.seed = o.seed;
  std::string why;
  const auto view = calib::RenderTarget(target, truth_camera,
                                        calib::PoseFacingTarget(target, config.topographer.b_mm), render, &why);
  if (!view) throw std::runtime_error(fmt::format("sigma {}: rendering the calibration target: {}", sigma, why));
  const auto observed = calib::DetectTarget(target, view->image, calib::DetectionOptions{});
  if (!observed) throw std::runtime_error(fmt::format("sigma {}: no calibration target found in its image", sigma));

  calib::CalibrationOptions co;
  co.model = calib::DistortionModelKind::kSeidel;
  co.focal_mm = roi.a_mm;
  co.pixel_pitch_um = roi.pixel_pitch_um;
  co.distance_mm = config.topographer.b_mm;
  co.magnification = config.distortion.magnification;
  const auto result = calib::CalibrateSingleView(*observed, co);
  if (!result.ok() || !result.seidel) {
    throw std::runtime_error(fmt::format("sigma {}: calibration failed: {}", sigma, result.message));
  }
  const auto on_plane = DetectionPlaneModelOf(result.camera, roi);
  if (!on_plane.ok) {
    throw std::runtime_error(
        fmt::format("sigma {}: calibration not usable on the detection plane: {}", sigma, on_plane.message));
  }
  const model::Distortion* distortion = &on_plane.distortion;

  CalibrationOutcome out;
  out.sigma_estimated_per_mm2 = result.seidel->sigma_per_mm2;
  out.sigma_stddev_per_mm2 = result.seidel->sigma_stddev_per_mm2;
  out.residual_rms_px = result.rms_px;
  out.corners = result.corners_used;
  out.distortion = *distortion;
  return out;
}

}  // namespace

ClosedLoopResult RunClosedLoop(const model::Config& config, double sigma, const ClosedLoopOptions& o) {
  const model::TopographerCamera roi = RegionOfInterest(o);
  ClosedLoopResult r;
  r.sigma_per_mm2 = sigma;
  // (i) calibration at the cornea position.
  r.calibration = Calibrate(config, roi, CameraThrough(roi, config, sigma), o, sigma);

  // (ii) the raw spot image through the same (distorted) camera.
  const model::SeidelParams truth_distortion = config.distortion.SeidelAt(sigma);
  const auto truth = correct::SpotsOnSensor(model::Biconic{config.cornea}, config.ideal_image, config.topographer,
                                            truth_distortion, roi);
  correct::SpotRenderOptions spot_options;
  spot_options.shape = correct::SpotShape::kEllipse;
  spot_options.psf_sigma_px = o.spot_psf_px;
  spot_options.read_noise_dn = o.spot_read_noise_dn;
  spot_options.seed = o.seed;
  const cv::Mat image = correct::RenderSpotImage(truth.spots, roi.width_px, roi.height_px, spot_options);

  // (iii) detect, index, undistort, reconstruct.
  SpotMeasurement measured;
  try {
    measured = MeasureSpots(image, roi, config.ideal_image, r.calibration.distortion);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("sigma {}: {}", sigma, e.what()));
  }
  r.spots_indexed = measured.indexed;
  r.spots_unassigned = measured.unassigned;
  r.spots_missing = measured.missing;
  r.undistort_failures = measured.undistort_failures;
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  try {
    r.corrected = topo::AnalyzeSpots(measured.spots, design.targets, config, &config.cornea);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("sigma {}: corrected spots: {}", sigma, e.what()));
  }
  return r;
}

}  // namespace topocal::pipeline
