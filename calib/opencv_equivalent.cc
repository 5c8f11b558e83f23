#include "calib/opencv_equivalent.h"

#include <array>
#include <cmath>
#include <vector>

#include <ceres/ceres.h>

namespace topocal::calib {
namespace {

// A 41 x 41 grid of pixels spanning the image; its undistorted rays are what both models must agree on.
constexpr int kGridSteps = 40;

struct OpenCvFitCost {
  OpenCvFitCost(const Eigen::Vector2d& u, const Eigen::Vector2d& px) : u_(u), px_(px) {}
  template <typename T>
  bool operator()(const T* intrinsics, const T* dist, T* residual) const {
    const T zero[2] = {T(0), T(0)};
    const T u[2] = {T(u_.x()), T(u_.y())};
    T px[2];
    model::CameraModel::NormalizedToPixel<model::BrownConrady>(intrinsics, dist, zero, u, px);
    residual[0] = px[0] - T(px_.x());
    residual[1] = px[1] - T(px_.y());
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& u, const Eigen::Vector2d& px) {
    return new ceres::AutoDiffCostFunction<OpenCvFitCost, 2, 4, 5>(new OpenCvFitCost(u, px));
  }
  Eigen::Vector2d u_, px_;
};

}  // namespace

std::optional<OpenCvEquivalent> ToOpenCvModel(const model::CameraModel& camera) {
  OpenCvEquivalent out;
  out.camera = camera;
  if (camera.distortion_centre.isZero(0)) return out;
  // A distortion centre is fitted with Brown-Conrady's coefficients only (calib::CalibrationOptions).
  if (!std::holds_alternative<model::BrownConrady>(camera.lens)) return std::nullopt;

  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> samples;  // (u, px)
  for (int i = 0; i <= kGridSteps; ++i) {
    for (int j = 0; j <= kGridSteps; ++j) {
      const Eigen::Vector2d px((camera.width_px - 1) * i / double(kGridSteps),
                               (camera.height_px - 1) * j / double(kGridSteps));
      // Pixels beyond the fold of strong barrel distortion have no ray; they are outside the model's domain.
      if (const auto u = camera.PixelToNormalized(px)) samples.emplace_back(*u, px);
    }
  }
  constexpr int kGridPoints = (kGridSteps + 1) * (kGridSteps + 1);
  if (2 * static_cast<int>(samples.size()) < kGridPoints) return std::nullopt;
  const double k1 = camera.dist[0];
  const Eigen::Vector2d e = camera.distortion_centre;
  std::array<double, 4> intrinsics = {camera.fx_px, camera.fy_px, camera.cx_px + camera.fx_px * e.x(),
                                      camera.cy_px + camera.fy_px * e.y()};
  std::array<double, 5> dist = {k1, camera.dist[1], camera.dist[2] - k1 * e.y(), camera.dist[3] - k1 * e.x(),
                                camera.dist[4]};
  ceres::Problem problem;
  for (const auto& [u, px] : samples) {
    problem.AddResidualBlock(OpenCvFitCost::Create(u, px), nullptr, intrinsics.data(), dist.data());
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 100;
  options.function_tolerance = 1e-15;
  options.parameter_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (summary.termination_type != ceres::CONVERGENCE) return std::nullopt;

  out.camera.fx_px = intrinsics[0];
  out.camera.fy_px = intrinsics[1];
  out.camera.cx_px = intrinsics[2];
  out.camera.cy_px = intrinsics[3];
  out.camera.dist = {};
  std::copy(dist.begin(), dist.end(), out.camera.dist.begin());
  out.camera.distortion_centre.setZero();
  for (const auto& [u, px] : samples) {
    const Eigen::Vector3d ray(u.x(), u.y(), 1.0);
    const double err = (out.camera.Project(ray) - px).norm();
    if (!std::isfinite(err)) return std::nullopt;
    out.max_error_px = std::max(out.max_error_px, err);
  }
  return out;
}

}  // namespace topocal::calib
