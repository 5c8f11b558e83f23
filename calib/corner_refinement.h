#pragma once
// Sub-pixel refinement of checkerboard corners by an iterated saddle-point fit.
//
// Why it is unbiased: at an X-junction of a checkerboard, opposite sectors have the same colour, so the pattern
// is point-symmetric about the corner for ANY two edge directions (any view, perspective being locally affine),
// and stays so after a point-symmetric blur and pixel integration: I(c + d) = I(c - d). The weighted least-squares
// fit of f(d) = a dx^2 + b dx dy + c dy^2 + d_x dx + d_y dy + e with Gaussian weights centred at c therefore has
// zero odd coefficients (d_x = d_y = 0), i.e. its stationary point is c itself. Iterating "fit around the current
// estimate, move to the fit's stationary point" has the corner as its fixed point, whatever the blur or angle.
// What remains is noise, the slight bending of edges by lens distortion across the window, and the sampling of
// a blurred image on the pixel grid (negligible once the blur sigma is >= ~0.7 px).
//
// cv::cornerSubPix (gradient-orthogonality in an 11 x 11 window) carries a bias of a few hundredths of a pixel on
// blurred renders because neighbouring edges and the unweighted window break that symmetry.
#include <optional>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace topocal::calib {

struct SaddleFitOptions {
  double window_sigma_px = 2.0;  // Gaussian weight sigma; the window extends to 3 sigma
  int max_iterations = 30;
  double convergence_px = 1e-4;  // stop when a step is shorter than this
  double max_shift_px = 3.0;     // a corner that wanders further from its start is rejected
};

// Half-width (px) of the pixel window the fit reads around the (rounded) corner for a weight sigma, and the largest
// sigma whose window stays within room_px of the corner (for corners near the image edge).
int SaddleWindowHalfWidthPx(double window_sigma_px) noexcept;
double SaddleSigmaForRoomPx(double room_px) noexcept;

// Refines one corner of an 8-bit or float grey image; nullopt if the window leaves the image, the fit is not a
// saddle (no X-junction there), or the iteration does not converge.
std::optional<Eigen::Vector2d> RefineSaddle(const cv::Mat& gray, const Eigen::Vector2d& initial_px,
                                            const SaddleFitOptions& options = {});

}  // namespace topocal::calib
