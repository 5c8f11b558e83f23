#include "model/opencv_view.h"

#include <cmath>
#include <type_traits>
#include <variant>

#include <fmt/format.h>

#include "model/device.h"

namespace topocal::model {

LensOnDetectionPlane LensFromOpenCv(const CameraModel& k, const TopographerCamera& camera) {
  const auto fail = [](std::string m) {
    LensOnDetectionPlane failed;
    failed.message = std::move(m);
    return failed;
  };
  if (!(k.fx_px > 0) || !(k.fy_px > 0) || !std::isfinite(k.fx_px) || !std::isfinite(k.fy_px)) {
    return fail(fmt::format("focal lengths must be > 0 (fx = {}, fy = {})", k.fx_px, k.fy_px));
  }
  if (!std::isfinite(k.cx_px) || !std::isfinite(k.cy_px)) return fail("principal point must be finite");
  for (const double d : k.dist) {
    if (!std::isfinite(d)) return fail("distortion coefficients must be finite");
  }
  LensOnDetectionPlane out;
  const Eigen::Matrix2d mt = camera.Orientation().transpose();
  const Eigen::Vector2d p = camera.PitchesMm();
  // The focal length in mm along each pixel axis, f_x p_u and f_y p_v: one distance a when the camera's pixel aspect
  // is the calibration's f_x / f_y.
  const double focal_u_mm = k.fx_px * p.x(), focal_v_mm = k.fy_px * p.y();
  out.lens.focal_mm = std::sqrt(focal_u_mm * focal_v_mm);
  if (!k.distortion_centre.allFinite()) return fail("distortion centre must be finite");
  const Eigen::Vector2d centre_mm =
      mt * Eigen::Vector2d(k.cx_px - camera.principal_point_px.x() + k.fx_px * k.distortion_centre.x(),
                           k.cy_px - camera.principal_point_px.y() + k.fy_px * k.distortion_centre.y())
               .cwiseProduct(p);
  out.lens.centre_x_mm = centre_mm.x();
  out.lens.centre_y_mm = centre_mm.y();
  // The tangential terms are r^2 q + 2 (n.q) n with q = (p2, p1): q turns with the frame, q_mm = M^T q_cv.
  // Every lens model of the list shares the tangential pair (model/lens_model.h); its radial terms are unchanged.
  const Eigen::Vector2d q_mm = mt * Eigen::Vector2d(k.dist[3], k.dist[2]);
  out.lens.model = k.lens;
  out.lens.k = k.dist;
  out.lens.k[2] = q_mm.y();
  out.lens.k[3] = q_mm.x();
  out.aspect_error = std::abs(focal_u_mm / focal_v_mm - 1.0);
  out.ok = true;
  return out;
}

CameraModel OpenCvFromLens(const LensParams& brown, const TopographerCamera& camera) {
  CameraModel k;
  k.width_px = camera.width_px;
  k.height_px = camera.height_px;
  const Eigen::Matrix2d m = camera.Orientation();
  const Eigen::Vector2d p = camera.PitchesMm();
  k.fx_px = brown.focal_mm / p.x();
  k.fy_px = brown.focal_mm / p.y();
  const Eigen::Vector2d c =
      camera.principal_point_px + (m * Eigen::Vector2d(brown.centre_x_mm, brown.centre_y_mm)).cwiseQuotient(p);
  k.cx_px = c.x();
  k.cy_px = c.y();
  // LensFromOpenCv's q_mm = M^T q_cv with q = (p2, p1), turned back.
  const Eigen::Vector2d q_cv = m * Eigen::Vector2d(brown.k[3], brown.k[2]);
  k.lens = brown.model;
  k.dist = brown.k;
  k.dist[2] = q_cv.y();
  k.dist[3] = q_cv.x();
  return k;
}

CameraModel OpenCvView(const Device& device) {
  const LensParams lens = std::visit(
      [&](const auto& d) -> LensParams {
        if constexpr (std::is_same_v<std::decay_t<decltype(d)>, SeidelParams>) {
          return SeidelToBrown(d, device.camera.a_mm);
        } else {
          return d;
        }
      },
      device.distortion);
  return OpenCvFromLens(lens, device.camera);
}

}  // namespace topocal::model
