#pragma once
// Lens-distortion models on the detection plane, in millimetres.
//
// Two models, each a small static struct whose templated kernel runs on double and on Ceres jets alike, so
// the same definition serves simulation (model/), autodiff fitting (calib/) and correction (correct/):
//
//  * SeidelRadial — third-order Seidel distortion, paper Eq. 18:
//        x_d = x_u + (sigma / M_T^3) * r^2 * x_u,   r^2 = x_u^2 + y_u^2   (about an optional centre)
//    sigma in mm^-2, M_T the transverse magnification (dimensionless, negative: the image is inverted).
//    Only sigma/M_T^3 matters; M_T is carried so that sigma keeps the paper's meaning. sigma > 0 with M_T < 0 is
//    barrel (the image shrinks); sigma < 0 is pincushion.
//
//  * BrownConrady — radial-tangential distortion in OpenCV's convention, on normalised coordinates
//    (x_n = (x - c_x) / f):
//        x_d = x_n (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x_n y_n + p2 (r^2 + 2 x_n^2)
//        y_d = y_n (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y_n^2) + 2 p2 x_n y_n
//    Coefficient order k1, k2, p1, p2, k3 as in cv::calibrateCamera's distCoeffs.
//
// Both inverses are Newton iterations with a residual check: they return false (never a silent guess) when the
// point lies outside the model's invertible domain (e.g. beyond the fold of strong barrel distortion) or the
// iteration does not reach the tolerance.
#include <array>
#include <optional>
#include <string>
#include <variant>

#include <Eigen/Core>

namespace topocal::model {

// Largest distance between Distort(Undistort(p)) and p accepted as a converged inverse, mm. Newton reaches
// ~1e-16 mm in a few steps on the paper's 0.5 mm field; 1e-12 mm leaves room for larger fields in px-scale units.
inline constexpr double kInverseToleranceMm = 1e-12;
inline constexpr int kInverseMaxIterations = 50;

struct SeidelRadial {
  static constexpr int kNumParams = 4;
  enum Index : int { kSigma = 0, kMagnification = 1, kCentreX = 2, kCentreY = 3 };

  template <typename T>
  static void Distort(const T* params, const T* undistorted_mm, T* distorted_mm) noexcept {
    const T c = params[kSigma] / (params[kMagnification] * params[kMagnification] * params[kMagnification]);
    const T x = undistorted_mm[0] - params[kCentreX];
    const T y = undistorted_mm[1] - params[kCentreY];
    const T f = T(1) + c * (x * x + y * y);
    distorted_mm[0] = params[kCentreX] + f * x;
    distorted_mm[1] = params[kCentreY] + f * y;
  }
  // Inverts Distort; false when the point has no preimage (beyond the barrel fold) or Newton does not converge.
  static bool Undistort(const double* params, const double* distorted_mm, double* undistorted_mm) noexcept;
};

struct BrownConrady {
  static constexpr int kNumParams = 5;
  enum Index : int { kK1 = 0, kK2 = 1, kP1 = 2, kP2 = 3, kK3 = 4 };

  template <typename T>
  static void DistortNormalized(const T* k, const T* xn, T* xd) noexcept {
    const T x = xn[0], y = xn[1];
    const T r2 = x * x + y * y;
    const T radial = T(1) + r2 * (k[kK1] + r2 * (k[kK2] + r2 * k[kK3]));
    xd[0] = x * radial + T(2) * k[kP1] * x * y + k[kP2] * (r2 + T(2) * x * x);
    xd[1] = y * radial + k[kP1] * (r2 + T(2) * y * y) + T(2) * k[kP2] * x * y;
  }
  // Inverts DistortNormalized to kInverseToleranceMm / scale; false when it does not converge.
  static bool UndistortNormalized(const double* k, const double* xd, double* xn, double tolerance = 1e-14) noexcept;
};

// Parameters of each model as used on the detection plane (mm).
struct SeidelParams {
  double sigma_per_mm2 = 0.0;
  double magnification = -0.065;  // M_T, paper Table IV
  double centre_x_mm = 0.0;
  double centre_y_mm = 0.0;
  std::array<double, SeidelRadial::kNumParams> AsArray() const {
    return {sigma_per_mm2, magnification, centre_x_mm, centre_y_mm};
  }
};

struct BrownParams {
  double focal_mm = 5.2;        // pinhole-to-detection-plane distance (the paper's a)
  double centre_x_mm = 0.0;     // principal point on the detection plane
  double centre_y_mm = 0.0;
  std::array<double, BrownConrady::kNumParams> k{};  // k1, k2, p1, p2, k3
};

// The distortion of a camera, chosen at run time.
using Distortion = std::variant<SeidelParams, BrownParams>;

// Forward map undistorted -> distorted on the detection plane, mm.
Eigen::Vector2d Distort(const Distortion& distortion, const Eigen::Vector2d& undistorted_mm) noexcept;
// Converged inverse; std::nullopt when the point has no preimage or the iteration fails.
std::optional<Eigen::Vector2d> Undistort(const Distortion& distortion, const Eigen::Vector2d& distorted_mm) noexcept;

// Seidel sigma <-> Brown k1 for the same radial distortion about the same centre, with the detection plane at
// focal distance f from the pinhole: sigma / M_T^3 * r_mm^2 = k1 * (r_mm / f)^2  =>  k1 = sigma f^2 / M_T^3.
double SeidelSigmaToBrownK1(double sigma_per_mm2, double magnification, double focal_mm) noexcept;
double BrownK1ToSeidelSigma(double k1, double magnification, double focal_mm) noexcept;
// The Brown parameters equivalent to a Seidel distortion (k2 = p1 = p2 = k3 = 0).
BrownParams SeidelToBrown(const SeidelParams& seidel, double focal_mm) noexcept;

std::string DescribeDistortion(const Distortion& distortion);

}  // namespace topocal::model
