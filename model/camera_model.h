#pragma once
// The pinhole camera with lens distortion that calibration fits and that renderers image through.
//
//   point_in_cam (mm, z forward) --> normalised u = (X/Z, Y/Z) --> distorted d --> pixel (fx d_x + cx, fy d_y + cy)
//
// Distortion on normalised coordinates, one of the lens models of OpenCV's distCoeffs family (model/lens_model.h:
// Brown-Conrady k1, k2, p1, p2, k3 unless set, or the rational model). The radial part may be centred at an offset e
// (normalised units) from the principal point: with v = u - e, d = e + distort(v). e = 0 is exactly OpenCV's model
// (what cv::undistort applies); the Seidel model of paper Eq. 18 is Brown's k1 alone with an optional centre e
// (sigma = k1 M_T^3 / f_mm^2, model/distortion.h).
// Pixel convention: OpenCV's (centre of the top-left pixel at (0, 0)).
#include <Eigen/Core>
#include <array>
#include <optional>

#include "model/lens_model.h"

namespace topocal::model {

struct CameraModel {
  int width_px = 0;
  int height_px = 0;
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  LensCoefficients dist{};                  // the lens model's, OpenCV's distCoeffs order; later entries zero
  Eigen::Vector2d distortion_centre{0, 0};  // e, normalised; zero for the OpenCV model
  LensModelId lens{};                       // Brown-Conrady unless set

  // Templated kernel (double or Ceres jet) of lens model M: normalised undistorted -> pixel.
  template <LensModel M, typename T>
  static void NormalizedToPixel(const T* intrinsics /* fx, fy, cx, cy */, const T* dist /* M's coefficients */,
                                const T* centre /* e_x, e_y */, const T* u, T* px) noexcept {
    const T v[2] = {u[0] - centre[0], u[1] - centre[1]};
    T d[2];
    M::DistortNormalized(dist, v, d);
    px[0] = intrinsics[0] * (d[0] + centre[0]) + intrinsics[2];
    px[1] = intrinsics[1] * (d[1] + centre[1]) + intrinsics[3];
  }
  // The same with the model chosen at run time.
  template <typename T>
  static void NormalizedToPixel(const LensModelId& lens, const T* intrinsics, const T* dist, const T* centre,
                                const T* u, T* px) noexcept {
    std::visit([&](auto m) { NormalizedToPixel<decltype(m)>(intrinsics, dist, centre, u, px); }, lens);
  }

  Eigen::Vector2d Project(const Eigen::Vector3d& point_in_cam) const noexcept {
    const double in[4] = {fx_px, fy_px, cx_px, cy_px};
    const double u[2] = {point_in_cam.x() / point_in_cam.z(), point_in_cam.y() / point_in_cam.z()};
    Eigen::Vector2d px;
    NormalizedToPixel(lens, in, dist.data(), distortion_centre.data(), u, px.data());
    return px;
  }

  // The undistorted normalised coordinates (X/Z, Y/Z) seen at a pixel; nullopt if the inverse does not converge.
  std::optional<Eigen::Vector2d> PixelToNormalized(const Eigen::Vector2d& px) const noexcept {
    const double d[2] = {(px.x() - cx_px) / fx_px - distortion_centre.x(),
                         (px.y() - cy_px) / fy_px - distortion_centre.y()};
    double v[2];
    // 1e-6 px expressed in normalised units.
    if (!UndistortNormalized(lens, dist.data(), d, v, 1e-6 / fx_px)) return std::nullopt;
    return Eigen::Vector2d(v[0] + distortion_centre.x(), v[1] + distortion_centre.y());
  }
};

}  // namespace topocal::model
