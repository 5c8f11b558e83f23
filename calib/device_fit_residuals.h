#pragma once
// The residuals of the device fit (calib/device_fit.h): a ball's spot and a target view's corner, both predicted
// through the device's one projection (model::ProjectBallSpot, model::ProjectPoint) and divided by their noise.
// Internal to calib/device_fit.cc.
#include <type_traits>

#include <Eigen/Core>
#include <ceres/ceres.h>
#include <ceres/normal_prior.h>
#include <ceres/rotation.h>

#include "model/device.h"

namespace topocal::calib::device_fit {

// One spot of one ball image: predicted - observed pixel, divided by the spot noise. The ball's vertex is ball[0..2]
// with z_offset added to its z: the shared offset of the balls' stage positions when they are known (ball_steps_mm),
// held at 0 otherwise.
template <int kDistortionParams>
struct BallSpotResidual {
  model::DeviceProjectionSetup setup;
  double radius_mm;
  double reference_radius_mm;
  Eigen::Vector3d designed_target_mm;
  Eigen::Vector2d designed_on_sphere_mm;
  Eigen::Vector2d observed_px;
  double inv_sigma_px;

  template <typename T>
  bool operator()(const T* pose, const T* radial_scale, const T* principal, const T* a, const T* distortion,
                  const T* ball, const T* z_offset, T* residual) const {
    const auto value = [](const T& v) -> double {
      if constexpr (std::is_same_v<T, double>) return v; else return v.a;
    };
    // Newton start: the reflection point on a ball of another radius has about the same normal as on the
    // reference sphere, so it sits at centre + (R / r_e) (designed point - reference centre) laterally.
    const Eigen::Vector2d initial = designed_on_sphere_mm * (radius_mm / reference_radius_mm) +
                                    Eigen::Vector2d(value(ball[0]), value(ball[1]));
    const T vertex[3] = {ball[0], ball[1], ball[2] + z_offset[0]};
    T px[2];
    if (!model::ProjectBallSpot(setup, pose, radial_scale, principal, a, distortion, vertex, radius_mm,
                                designed_target_mm.data(), initial, px)) {
      return false;
    }
    residual[0] = (px[0] - observed_px.x()) * inv_sigma_px;
    residual[1] = (px[1] - observed_px.y()) * inv_sigma_px;
    return true;
  }
};

template <int N>
ceres::CostFunction* MakeSpotCost(const BallSpotResidual<N>& r) {
  return new ceres::AutoDiffCostFunction<BallSpotResidual<N>, 2, model::ScreenPose::kNumParams, 1, 2, 1, N, 3, 1>(
      new BallSpotResidual<N>(r));
}

// One corner of one target view: predicted - observed pixel, divided by the corner noise. board[6]: the target's
// angle-axis rotation (rad) and translation (mm) into the topographer's frame; the camera is the balls' camera.
template <int kDistortionParams>
struct CornerResidual {
  model::DeviceProjectionSetup setup;
  Eigen::Vector3d board_mm;
  Eigen::Vector2d observed_px;
  double inv_sigma_px;

  template <typename T>
  bool operator()(const T* board, const T* principal, const T* a, const T* distortion, T* residual) const {
    const T on_board[3] = {T(board_mm.x()), T(board_mm.y()), T(board_mm.z())};
    T point[3];
    ceres::AngleAxisRotatePoint(board, on_board, point);
    for (int i = 0; i < 3; ++i) point[i] += board[3 + i];
    if (!(point[2] + setup.b_mm > T(0.0))) return false;  // behind the pinhole
    T px[2];
    model::ProjectPoint(setup, principal, a, distortion, point, px);
    residual[0] = (px[0] - observed_px.x()) * inv_sigma_px;
    residual[1] = (px[1] - observed_px.y()) * inv_sigma_px;
    return true;
  }
};

template <int N>
ceres::CostFunction* MakeCornerCost(const CornerResidual<N>& r) {
  return new ceres::AutoDiffCostFunction<CornerResidual<N>, 2, 6, 2, 1, N>(new CornerResidual<N>(r));
}

// A diagonal Gaussian prior: (x - mean) / sigma per component.
inline ceres::CostFunction* Prior(const Eigen::VectorXd& mean, const Eigen::VectorXd& sigma) {
  const Eigen::MatrixXd a = sigma.cwiseInverse().asDiagonal();
  return new ceres::NormalPrior(a, mean);
}

}  // namespace topocal::calib::device_fit
