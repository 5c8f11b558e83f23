#include "model/distortion.h"

#include <cmath>
#include <limits>

#include <type_traits>

#include <fmt/format.h>

namespace topocal::model {

bool SeidelRadial::Undistort(const double* params, const double* distorted_mm, double* undistorted_mm) noexcept {
  const auto forward = [params](const auto* in, auto* out) {
    using T = std::remove_cv_t<std::remove_reference_t<decltype(in[0])>>;
    const T p[kNumParams] = {T(params[0]), T(params[1]), T(params[2]), T(params[3])};
    Distort(p, in, out);
  };
  if (!InvertByNewton(forward, distorted_mm, undistorted_mm, kInverseToleranceMm)) return false;
  // Newton may land on the far branch beyond the fold of barrel distortion (r^2 > 1/(3|c|)): reject it, since the
  // physical image never reaches there.
  const double dx = undistorted_mm[0] - params[kCentreX], dy = undistorted_mm[1] - params[kCentreY];
  return RadialDerivative(Coefficient(params), dx * dx + dy * dy) > 0.0;
}

double SeidelRadial::FoldRadiusSquaredMm2(double c, double radial_derivative) noexcept {
  if (c >= 0) return std::numeric_limits<double>::infinity();
  return (1.0 - radial_derivative) / (-3.0 * c);  // RadialDerivative(c, r^2) = radial_derivative
}

double SeidelRadial::MaxFoldFreeSigmaPerMm2(double magnification, double radius_mm) noexcept {
  const double m = std::abs(magnification);
  return m * m * m / (3 * radius_mm * radius_mm);
}

namespace {
struct ForwardVisitor {
  const Eigen::Vector2d& p;
  Eigen::Vector2d operator()(const SeidelParams& s) const {
    const auto params = s.AsArray();
    Eigen::Vector2d out;
    SeidelRadial::Distort(params.data(), p.data(), out.data());
    return out;
  }
  Eigen::Vector2d operator()(const LensParams& b) const {
    const double xn[2] = {(p.x() - b.centre_x_mm) / b.focal_mm, (p.y() - b.centre_y_mm) / b.focal_mm};
    double xd[2];
    DistortNormalized(b.model, b.k.data(), xn, xd);
    return {b.centre_x_mm + b.focal_mm * xd[0], b.centre_y_mm + b.focal_mm * xd[1]};
  }
};
struct InverseVisitor {
  const Eigen::Vector2d& p;
  std::optional<Eigen::Vector2d> operator()(const SeidelParams& s) const {
    const auto params = s.AsArray();
    Eigen::Vector2d out;
    if (!SeidelRadial::Undistort(params.data(), p.data(), out.data())) return std::nullopt;
    return out;
  }
  std::optional<Eigen::Vector2d> operator()(const LensParams& b) const {
    const double xd[2] = {(p.x() - b.centre_x_mm) / b.focal_mm, (p.y() - b.centre_y_mm) / b.focal_mm};
    double xn[2];
    if (!UndistortNormalized(b.model, b.k.data(), xd, xn, kInverseToleranceMm / b.focal_mm)) return std::nullopt;
    return Eigen::Vector2d(b.centre_x_mm + b.focal_mm * xn[0], b.centre_y_mm + b.focal_mm * xn[1]);
  }
};
}  // namespace

Eigen::Vector2d DistortionCentreMm(const Distortion& distortion) noexcept {
  if (const auto* s = std::get_if<SeidelParams>(&distortion)) return {s->centre_x_mm, s->centre_y_mm};
  const auto& b = std::get<LensParams>(distortion);
  return {b.centre_x_mm, b.centre_y_mm};
}

Eigen::Vector2d Distort(const Distortion& distortion, const Eigen::Vector2d& undistorted_mm) noexcept {
  return std::visit(ForwardVisitor{undistorted_mm}, distortion);
}

std::optional<Eigen::Vector2d> Undistort(const Distortion& distortion, const Eigen::Vector2d& distorted_mm) noexcept {
  return std::visit(InverseVisitor{distorted_mm}, distortion);
}

double SeidelSigmaToBrownK1(double sigma_per_mm2, double magnification, double focal_mm) noexcept {
  return sigma_per_mm2 * focal_mm * focal_mm / (magnification * magnification * magnification);
}

double BrownK1ToSeidelSigma(double k1, double magnification, double focal_mm) noexcept {
  return k1 * magnification * magnification * magnification / (focal_mm * focal_mm);
}

LensParams SeidelToBrown(const SeidelParams& seidel, double focal_mm) noexcept {
  LensParams b;
  b.focal_mm = focal_mm;
  b.centre_x_mm = seidel.centre_x_mm;
  b.centre_y_mm = seidel.centre_y_mm;
  b.model = BrownConrady{};
  b.k = {SeidelSigmaToBrownK1(seidel.sigma_per_mm2, seidel.magnification, focal_mm)};
  return b;
}

namespace {

// First s in [0, s_max] where g(s) <= level, by a scan fine enough not to step over a root of a low-order polynomial
// or rational function in s (1000 steps) and bisection to machine precision; +inf if g stays above.
template <typename G>
double FirstRootOf(const G& g, double level, double s_max) {
  constexpr int kSteps = 1000;
  double s_prev = 0.0;
  for (int i = 1; i <= kSteps; ++i) {
    const double s = s_max * i / kSteps;
    if (g(s) <= level) {
      double lo = s_prev, hi = s;
      for (int it = 0; it < 100 && hi - lo > 1e-15 * s_max; ++it) {
        const double mid = 0.5 * (lo + hi);
        (g(mid) > level ? lo : hi) = mid;
      }
      return lo;
    }
    s_prev = s;
  }
  return std::numeric_limits<double>::infinity();
}

}  // namespace

double FoldRadiusMm(const Distortion& distortion, double max_radius_mm, double radial_derivative) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (const auto* s = std::get_if<SeidelParams>(&distortion)) {
    const auto params = s->AsArray();
    const double r =
        std::sqrt(SeidelRadial::FoldRadiusSquaredMm2(SeidelRadial::Coefficient(params.data()), radial_derivative));
    return r < max_radius_mm ? r : kInf;
  }
  const auto& b = std::get<LensParams>(distortion);
  const auto g = [&](double s) { return RadialSlope(b.model, b.k.data(), s); };
  const double s_max = std::pow(max_radius_mm / b.focal_mm, 2);
  const double s_fold = FirstRootOf(g, radial_derivative, s_max);
  return std::isfinite(s_fold) ? b.focal_mm * std::sqrt(s_fold) : kInf;
}

std::string DescribeDistortion(const Distortion& distortion) {
  if (const auto* s = std::get_if<SeidelParams>(&distortion)) {
    return fmt::format("seidel sigma={:.6g}/mm^2 M_T={:.6g} centre=({:.6g}, {:.6g}) mm", s->sigma_per_mm2,
                       s->magnification, s->centre_x_mm, s->centre_y_mm);
  }
  const auto& b = std::get<LensParams>(distortion);
  std::string out = fmt::format("{} f={:.6g} mm centre=({:.6g}, {:.6g}) mm",
                                LensModelName(b.model, LensNaming::kDevice), b.focal_mm, b.centre_x_mm, b.centre_y_mm);
  const auto names = LensParameterNames(b.model);
  for (size_t i = 0; i < names.size(); ++i) out += fmt::format(" {}={:.6g}", names[i], b.k[i]);
  return out;
}

}  // namespace topocal::model
