#include "pipeline/detection_plane.h"

#include <fmt/format.h>

#include "correct/opencv_brown.h"

namespace topocal::pipeline {

std::optional<model::Distortion> DistortionOnDetectionPlane(const calib::CameraModel& c,
                                                            const model::TopographerCamera& camera, std::string* why) {
  correct::OpenCvCamera k;
  k.fx_px = c.fx_px;
  k.fy_px = c.fy_px;
  k.cx_px = c.cx_px;
  k.cy_px = c.cy_px;
  k.dist.assign(c.dist.begin(), c.dist.end());
  k.centre_x = c.distortion_centre.x();
  k.centre_y = c.distortion_centre.y();
  const auto brown = correct::BrownFromOpenCv(k, camera, why);
  if (!brown) return std::nullopt;
  if (brown->aspect_error > kMaxAspectError) {
    if (why) {
      *why = fmt::format("fx / fy = {:.6f}; the detection-plane model has one focal length and accepts "
                         "|fx / fy - 1| <= {}", c.fx_px / c.fy_px, kMaxAspectError);
    }
    return std::nullopt;
  }
  return model::Distortion{brown->brown};
}

}  // namespace topocal::pipeline
