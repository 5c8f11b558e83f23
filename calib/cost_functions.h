#pragma once
// Ceres cost functions of camera calibration.
//
// Reprojection of one target corner (paper-independent; Zhang 2000, Eq. 2 with OpenCV's distortion):
//
//   corner_in_cam = R(cam_from_target[0..2]) * corner_in_target_mm + cam_from_target[3..5]     (angle-axis, mm)
//   u             = (X / Z, Y / Z)                                                               (normalised)
//   predicted_px  = CameraModel::NormalizedToPixel<Lens>(intrinsics, dist, centre, u)    (model/camera_model.h)
//   residual_px   = predicted_px - observed_px
//
// Parameter blocks: intrinsics [fx, fy, cx, cy] px; dist [the lens model's coefficients, OpenCV's order]; centre
// [e_x, e_y] normalised; cam_from_target [angle-axis (rad), translation (mm)]; warp [sag_x, sag_y] mm (BoardWarp,
// held at 0 unless fitted). A corner behind the camera (Z <= 0) makes the evaluation fail, which Ceres treats as an
// infeasible step rather than a NaN.
#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <Eigen/Core>

#include "model/camera_model.h"

namespace topocal::calib {

inline constexpr int kNumIntrinsics = 4;
inline constexpr int kNumCentre = 2;
inline constexpr int kNumPose = 6;
inline constexpr int kNumWarp = 2;

// Board warp, the parabolic sag mrcal fits for printed targets that are not flat: the target point (x, y, 0)
// actually lies at z = sag_x (1 - x_r^2) + sag_y (1 - y_r^2), x_r = (x - centre_x) / half_width (and y), i.e. the
// board's middle is sag_x + sag_y mm off the plane through its edges (z into the target: positive = the middle is
// further from the camera than the edges). Valid for sags small against the board (a shallow cylinder/dome).
struct BoardWarp {
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();
  Eigen::Vector2d half_size_mm = Eigen::Vector2d::Ones();

  template <typename T>
  T SagMm(const T* warp, double x_mm, double y_mm) const noexcept {
    const double xr = (x_mm - centre_mm.x()) / half_size_mm.x(), yr = (y_mm - centre_mm.y()) / half_size_mm.y();
    return warp[0] * T(1.0 - xr * xr) + warp[1] * T(1.0 - yr * yr);
  }
};

template <model::LensModel Lens>
struct ReprojectionCost {
  ReprojectionCost(const Eigen::Vector2d& observed_px, const Eigen::Vector3d& corner_in_target_mm,
                   const BoardWarp& warp_geometry = {})
      : observed_px_(observed_px), corner_in_target_mm_(corner_in_target_mm), warp_geometry_(warp_geometry) {}

  template <typename T>
  bool operator()(const T* intrinsics, const T* dist, const T* centre, const T* cam_from_target, const T* warp,
                  T* residual_px) const {
    const T corner[3] = {T(corner_in_target_mm_.x()), T(corner_in_target_mm_.y()),
                         T(corner_in_target_mm_.z()) +
                             warp_geometry_.SagMm(warp, corner_in_target_mm_.x(), corner_in_target_mm_.y())};
    T corner_in_cam[3];
    ceres::AngleAxisRotatePoint(cam_from_target, corner, corner_in_cam);
    for (int i = 0; i < 3; ++i) corner_in_cam[i] += cam_from_target[3 + i];
    if (!(corner_in_cam[2] > T(0))) return false;
    const T u[2] = {corner_in_cam[0] / corner_in_cam[2], corner_in_cam[1] / corner_in_cam[2]};
    T px[2];
    model::CameraModel::NormalizedToPixel<Lens>(intrinsics, dist, centre, u, px);
    residual_px[0] = px[0] - T(observed_px_.x());
    residual_px[1] = px[1] - T(observed_px_.y());
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_px, const Eigen::Vector3d& corner_in_target_mm,
                                     const BoardWarp& warp_geometry) {
    return new ceres::AutoDiffCostFunction<ReprojectionCost, 2, kNumIntrinsics, Lens::kNumParams, kNumCentre,
                                           kNumPose, kNumWarp>(
        new ReprojectionCost(observed_px, corner_in_target_mm, warp_geometry));
  }

 private:
  Eigen::Vector2d observed_px_;
  Eigen::Vector3d corner_in_target_mm_;
  BoardWarp warp_geometry_;
};

}  // namespace topocal::calib
