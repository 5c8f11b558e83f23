#include "pipeline/detection_plane.h"

#include <algorithm>

#include <fmt/format.h>

#include "model/opencv_view.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// Samples per sensor side for the model error: the error grows with the distortion's displacement, largest at the
// sensor's edges and corners, which the grid includes.
constexpr int kErrorGridSteps = 16;

}  // namespace

DetectionPlaneModel DetectionPlaneModelUnverified(const model::CameraModel& c, const model::TopographerCamera& sensor) {
  DetectionPlaneModel result;
  result.camera = sensor;
  if (c.fx_px > 0 && c.fy_px > 0) result.camera.pixel_aspect = c.fx_px / c.fy_px;  // else LensFromOpenCv says why
  if (const auto why = result.camera.Invalid()) {
    result.message = fmt::format("fx / fy = {:.6f}: {}", c.fx_px / c.fy_px, *why);
    return result;
  }
  const auto brown = model::LensFromOpenCv(c, result.camera);
  if (!brown.ok) {
    result.message = brown.message;
    return result;
  }
  result.distortion = model::Distortion{brown.lens};
  result.ok = true;
  return result;
}

DetectionPlaneModel DetectionPlaneModelOf(const model::CameraModel& c, const model::TopographerCamera& sensor) {
  DetectionPlaneModel result = DetectionPlaneModelUnverified(c, sensor);
  if (!result.ok) return result;
  result.ok = false;
  const auto& camera = result.camera;
  for (int j = 0; j <= kErrorGridSteps; ++j) {
    for (int i = 0; i <= kErrorGridSteps; ++i) {
      const Eigen::Vector2d px((camera.width_px - 1.0) * i / kErrorGridSteps,
                               (camera.height_px - 1.0) * j / kErrorGridSteps);
      const auto normalised = c.PixelToNormalized(px);
      const auto undistorted_mm = model::Undistort(result.distortion, camera.DetectionPlaneFromPixel(px));
      // Beyond the distortion's fold neither side has an undistorted point to compare.
      if (!normalised || !undistorted_mm) continue;
      const Eigen::Vector2d exact_px(c.cx_px + c.fx_px * normalised->x(), c.cy_px + c.fy_px * normalised->y());
      result.model_error_px =
          std::max(result.model_error_px, (camera.PixelFromDetectionPlane(*undistorted_mm) - exact_px).norm());
    }
  }
  if (result.model_error_px > kMaxModelErrorPx) {
    result.message = fmt::format(
        "fx / fy = {:.6f}: the detection-plane model would misplace undistorted points by up to {:.3f} px "
        "(> {} px)",
        c.fx_px / c.fy_px, result.model_error_px, kMaxModelErrorPx);
    return result;
  }
  result.ok = true;
  return result;
}

DetectionPlaneModel CalibrationOnDetectionPlane(const calib::CalibrationFile& calibration,
                                                const std::string& calibration_path,
                                                const model::TopographerCamera& camera,
                                                const std::string& camera_path) {
  if (calibration.camera.width_px != camera.width_px || calibration.camera.height_px != camera.height_px) {
    throw util::InputError(fmt::format("{}: calibrated at {} x {} px but {} is {} x {} px: calibrate the same sensor",
                                       calibration_path, calibration.camera.width_px, calibration.camera.height_px,
                                       camera_path, camera.width_px, camera.height_px));
  }
  auto on_plane = DetectionPlaneModelOf(calibration.camera, camera);
  if (!on_plane.ok) throw util::InputError(fmt::format("{}: {}", calibration_path, on_plane.message));
  return on_plane;
}

}  // namespace topocal::pipeline
