#include "calib/corner_refinement.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/LU>

namespace topocal::calib {

int SaddleWindowHalfWidthPx(double window_sigma_px) noexcept {
  return static_cast<int>(std::ceil(3.0 * window_sigma_px));
}

double SaddleSigmaForRoomPx(double room_px) noexcept { return std::max(0.0, std::floor(room_px) / 3.0); }

std::optional<Eigen::Vector2d> RefineSaddle(const cv::Mat& gray, const Eigen::Vector2d& initial_px,
                                            const SaddleFitOptions& options) {
  if (gray.empty() || gray.channels() != 1 || !(options.window_sigma_px > 0)) return std::nullopt;
  cv::Mat image;
  if (gray.depth() == CV_32F) {
    image = gray;
  } else {
    gray.convertTo(image, CV_32F);
  }
  const int radius = SaddleWindowHalfWidthPx(options.window_sigma_px);
  const double inv_two_sigma2 = 1.0 / (2.0 * options.window_sigma_px * options.window_sigma_px);
  Eigen::Vector2d centre = initial_px;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const int cx = static_cast<int>(std::lround(centre.x())), cy = static_cast<int>(std::lround(centre.y()));
    if (cx - radius < 0 || cy - radius < 0 || cx + radius >= image.cols || cy + radius >= image.rows) {
      return std::nullopt;
    }
    // Weighted normal equations of the quadratic surface in coordinates relative to the current centre.
    Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
    for (int y = cy - radius; y <= cy + radius; ++y) {
      const auto* row = image.ptr<float>(y);
      const double dy = y - centre.y();
      for (int x = cx - radius; x <= cx + radius; ++x) {
        const double dx = x - centre.x();
        const double w = std::exp(-(dx * dx + dy * dy) * inv_two_sigma2);
        const Eigen::Matrix<double, 6, 1> basis(dx * dx, dx * dy, dy * dy, dx, dy, 1.0);
        normal.selfadjointView<Eigen::Lower>().rankUpdate(basis, w);
        rhs += w * row[x] * basis;
      }
    }
    const Eigen::Matrix<double, 6, 1> coeff = normal.selfadjointView<Eigen::Lower>().ldlt().solve(rhs);
    // Gradient 0: [2a b; b 2c] delta = -[d_x; d_y]. A saddle has a negative Hessian determinant.
    Eigen::Matrix2d hessian;
    hessian << 2 * coeff[0], coeff[1], coeff[1], 2 * coeff[2];
    const double det = hessian.determinant();
    if (!(det < 0)) return std::nullopt;
    const Eigen::Vector2d step = hessian.inverse() * -Eigen::Vector2d(coeff[3], coeff[4]);
    if (!step.allFinite()) return std::nullopt;
    // Large steps come from a poor quadratic model far from the junction; move at most one pixel at a time.
    const double length = step.norm();
    centre += length > 1.0 ? Eigen::Vector2d(step / length) : step;
    if ((centre - initial_px).norm() > options.max_shift_px) return std::nullopt;
    if (length < options.convergence_px) return centre;
  }
  return std::nullopt;
}

}  // namespace topocal::calib
