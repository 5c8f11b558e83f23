#pragma once
// The lens models of OpenCV's distCoeffs family that a camera can carry: each one header (model/lens_*.h) behind the
// concept below, and one entry of the list `LensModels`, which generates the run-time choice (LensModelId), the
// names --model and the files accept, the parameter tables of the fits and the size of a coefficient block. A
// consumer dispatches with std::visit (or the functions below) and never names a model unless it must.
//
// Every model acts on normalised coordinates x_n = (x - c) / f (pixels, or the detection plane's mm with f = a),
// keeps its coefficients in OpenCV's distCoeffs order (so a prefix of OpenCV's vector), and has a radial factor g:
// without the tangential terms a point at radius r goes to r g(r^2). The paper's Seidel distortion (Eq. 18) is not in
// the list: it acts on millimetres with the magnification (model/distortion.h), and is k1 alone of Brown-Conrady.
//
// Adding a model: write model/lens_NAME.h with a struct satisfying LensModel, add it to LensModels. The calibration
// (calib/), the device fit, the files (calibration, device, ROS, mrcal), the undistortion and the reconstruction take
// it from there.
#include <algorithm>
#include <array>
#include <concepts>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>

#include <ceres/jet.h>

#include "model/lens_brown_conrady.h"
#include "model/lens_rational.h"

namespace topocal::model {

template <class M>
concept LensModel = requires(const double* k, const double* xn, double* xd, const ceres::Jet<double, 2>* kj,
                             const ceres::Jet<double, 2>* xj, ceres::Jet<double, 2>* dj, double s) {
  { M::kName } -> std::convertible_to<std::string_view>;        // calibration files and --model
  { M::kDeviceName } -> std::convertible_to<std::string_view>;  // device files
  { M::kRosName } -> std::convertible_to<std::string_view>;     // ROS camera_info's distortion_model
  { M::kMrcalName } -> std::convertible_to<std::string_view>;   // mrcal's lensmodel
  { M::kNumParams } -> std::convertible_to<int>;
  { M::kParameterNames[0] } -> std::convertible_to<std::string_view>;
  requires M::kParameterNames.size() == static_cast<size_t>(M::kNumParams);
  { M::RadialFactor(k, s) } -> std::same_as<double>;
  M::DistortNormalized(k, xn, xd);  // double
  M::DistortNormalized(kj, xj, dj);  // and Ceres jets: the fits differentiate it
};

template <LensModel... Ms>
struct LensModelList {
  using Variant = std::variant<Ms...>;
  static constexpr int kMaxParams = std::max({Ms::kNumParams...});
};

// The list. The first entry is the default (OpenCV's default model).
using LensModels = LensModelList<BrownConrady, RationalPolynomial>;

using LensModelId = LensModels::Variant;
inline constexpr int kMaxLensParams = LensModels::kMaxParams;
// A model's coefficients in its own (OpenCV's) order; the entries past its count are zero.
using LensCoefficients = std::array<double, kMaxLensParams>;

// Calls f(M{}) for each model M of the list, in order.
template <typename F>
void ForEachLensModel(F&& f) {
  [&]<typename... Ms>(LensModelList<Ms...>*) { (f(Ms{}), ...); }(static_cast<LensModels*>(nullptr));
}

// Which of a model's names: topocal's (calibration files, --model), a device file's, ROS camera_info's, mrcal's.
enum class LensNaming { kTopocal, kDevice, kRos, kMrcal };

std::string_view LensModelName(const LensModelId& lens, LensNaming naming = LensNaming::kTopocal) noexcept;
std::optional<LensModelId> LensModelFromName(std::string_view name, LensNaming naming = LensNaming::kTopocal) noexcept;
// The names of the list joined by `separator` ("brown5, rational8"), for messages and --help.
std::string LensModelNames(std::string_view separator = ", ", LensNaming naming = LensNaming::kTopocal);
int LensParameterCount(const LensModelId& lens) noexcept;
std::span<const std::string_view> LensParameterNames(const LensModelId& lens) noexcept;
// The model with the fewest coefficients that holds `k` exactly (its later entries zero): how a distCoeffs vector read
// from a file chooses its model.
LensModelId SmallestLensModelFor(const LensCoefficients& k) noexcept;

// x_d of x_n through the model (double or Ceres jets).
template <typename T>
void DistortNormalized(const LensModelId& lens, const T* k, const T* xn, T* xd) noexcept {
  std::visit([&](auto m) { decltype(m)::DistortNormalized(k, xn, xd); }, lens);
}
// The converged inverse of DistortNormalized (|forward(x_n) - x_d| <= tolerance); false when it does not converge or
// meets the fold.
bool UndistortNormalized(const LensModelId& lens, const double* k, const double* xd, double* xn,
                         double tolerance = 1e-14) noexcept;
// d r_d / d r of the radial part at s = r^2: g(s) + 2 s g'(s). Where g(s) <= 0 (points thrown through the centre, or
// a rational denominator past zero) -infinity: the map is folded there whatever the slope.
double RadialSlope(const LensModelId& lens, const double* k, double s) noexcept;

}  // namespace topocal::model
