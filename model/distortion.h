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
//  * a lens model of OpenCV's distCoeffs family (model/lens_model.h: Brown-Conrady, the rational model) on the
//    detection plane, on x_n = (x - c) / f with f the pinhole-to-detection-plane distance a and c the principal point
//    (mm): LensParams.
//
// Every inverse is a Newton iteration (model/invert_by_newton.h) with a residual check: it returns false (never a
// silent guess) when the point lies outside the model's invertible domain (e.g. beyond the fold of strong barrel
// distortion) or the iteration does not reach the tolerance.
#include <array>
#include <optional>
#include <string>
#include <variant>

#include <Eigen/Core>

#include "model/invert_by_newton.h"
#include "model/lens_model.h"
#include "model/paper_topographer.h"

namespace topocal::model {

struct SeidelRadial {
  static constexpr int kNumParams = 4;
  enum Index : int { kSigma = 0, kMagnification = 1, kCentreX = 2, kCentreY = 3 };

  template <typename T>
  static void Distort(const T* params, const T* undistorted_mm, T* distorted_mm) noexcept {
    DistortWithCoefficient(Coefficient(params), params[kCentreX], params[kCentreY], undistorted_mm, distorted_mm);
  }
  // The one coefficient of Eq. 18, c = sigma / M_T^3 (mm^-2 on the detection plane).
  template <typename T>
  static T Coefficient(const T* params) noexcept {
    return params[kSigma] / (params[kMagnification] * params[kMagnification] * params[kMagnification]);
  }
  // Eq. 18 with c computed once (a remap table evaluates it per pixel: correct/undistort_map.cc).
  template <typename T>
  static void DistortWithCoefficient(const T& c, const T& centre_x_mm, const T& centre_y_mm, const T* undistorted_mm,
                                     T* distorted_mm) noexcept {
    const T x = undistorted_mm[0] - centre_x_mm;
    const T y = undistorted_mm[1] - centre_y_mm;
    const T f = T(1) + c * (x * x + y * y);
    distorted_mm[0] = centre_x_mm + f * x;
    distorted_mm[1] = centre_y_mm + f * y;
  }
  // The fold of Eq. 18: r_d = r (1 + c r^2) about the centre, so d r_d / d r = 1 + 3 c r^2 (r2 = r^2, mm^2). Barrel
  // distortion (c < 0) folds where it vanishes, r^2 = 1 / (3 |c|): beyond, two points share one image.
  static double RadialDerivative(double c, double r2_mm2) noexcept { return 1.0 + 3.0 * c * r2_mm2; }
  // r^2 (mm^2) where the radial derivative falls to `radial_derivative` (0: the fold itself); +inf when it never does
  // (c >= 0).
  static double FoldRadiusSquaredMm2(double c, double radial_derivative = 0.0) noexcept;
  // The largest |sigma| (mm^-2) that leaves every point within radius_mm of the centre short of the fold:
  // 1 + 3 (-|sigma| / |M_T|^3) r^2 = 0  =>  |sigma| = |M_T|^3 / (3 r^2).
  static double MaxFoldFreeSigmaPerMm2(double magnification, double radius_mm) noexcept;
  // Inverts Distort; false when the point has no preimage (beyond the barrel fold) or Newton does not converge.
  static bool Undistort(const double* params, const double* distorted_mm, double* undistorted_mm) noexcept;
};

// Parameters of each model as used on the detection plane (mm).
struct SeidelParams {
  double sigma_per_mm2 = 0.0;
  double magnification = kPaperMagnification;  // M_T
  double centre_x_mm = 0.0;
  double centre_y_mm = 0.0;
  std::array<double, SeidelRadial::kNumParams> AsArray() const {
    return {sigma_per_mm2, magnification, centre_x_mm, centre_y_mm};
  }
};

struct LensParams {
  double focal_mm = kPaperAMm;  // pinhole-to-detection-plane distance (the paper's a)
  double centre_x_mm = 0.0;     // principal point on the detection plane
  double centre_y_mm = 0.0;
  LensModelId model{};          // Brown-Conrady unless set
  LensCoefficients k{};         // the model's coefficients in OpenCV's order (k1, k2, p1, p2, k3, ...)
};

// The distortion of a camera, chosen at run time.
using Distortion = std::variant<SeidelParams, LensParams>;

// The centre the model's radial part is symmetric about, on the detection plane (mm): Seidel's centre, Brown's
// principal point.
Eigen::Vector2d DistortionCentreMm(const Distortion& distortion) noexcept;

// Forward map undistorted -> distorted on the detection plane, mm.
Eigen::Vector2d Distort(const Distortion& distortion, const Eigen::Vector2d& undistorted_mm) noexcept;
// Converged inverse; std::nullopt when the point has no preimage or the iteration fails.
std::optional<Eigen::Vector2d> Undistort(const Distortion& distortion, const Eigen::Vector2d& distorted_mm) noexcept;

// Seidel sigma <-> Brown k1 for the same radial distortion about the same centre, with the detection plane at
// focal distance f from the pinhole: sigma / M_T^3 * r_mm^2 = k1 * (r_mm / f)^2  =>  k1 = sigma f^2 / M_T^3.
double SeidelSigmaToBrownK1(double sigma_per_mm2, double magnification, double focal_mm) noexcept;
double BrownK1ToSeidelSigma(double k1, double magnification, double focal_mm) noexcept;
// The Brown-Conrady parameters equivalent to a Seidel distortion (k2 = p1 = p2 = k3 = 0).
LensParams SeidelToBrown(const SeidelParams& seidel, double focal_mm) noexcept;

// Radius about the distortion centre (detection plane, mm) where the radial derivative d r_d / d r of the model
// first falls to `radial_derivative` (0: the fold, beyond which the map is not one-to-one), searched within
// max_radius_mm; +infinity if it does not fall there. Seidel: SeidelRadial::FoldRadiusSquaredMm2 (closed form).
// A lens model: d r_d / d r = g(s) + 2 s g'(s), s = (r / f)^2 (model::RadialSlope; the tangential terms are not
// radial), whose first root is found by a scan and bisection.
double FoldRadiusMm(const Distortion& distortion, double max_radius_mm, double radial_derivative);

std::string DescribeDistortion(const Distortion& distortion);

}  // namespace topocal::model
