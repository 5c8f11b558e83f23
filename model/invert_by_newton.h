#pragma once
// Newton's method on a 2-D map with its Jacobian taken by forward-mode jets: the inverse of every distortion model
// (model/distortion.h, model/lens_model.h). Written by hand because each call is a 2x2 solve on a hot path (every
// spot, every image pixel of a remap table); a ceres::Problem per point would cost ~100x more in set-up than the
// solve itself.
#include <cmath>

#include <ceres/jet.h>

namespace topocal::model {

// Largest distance between Distort(Undistort(p)) and p accepted as a converged inverse, mm. Newton reaches
// ~1e-16 mm in a few steps on the paper's 0.5 mm field; 1e-12 mm leaves room for larger fields in px-scale units.
inline constexpr double kInverseToleranceMm = 1e-12;
inline constexpr int kInverseMaxIterations = 50;

// `forward(in, out)` maps 2 jets to 2 jets. Starts at the target (distortion is a small perturbation); false when
// the residual turns non-finite, the Jacobian vanishes (the fold: no unique preimage) or the iterations run out.
template <typename Map>
bool InvertByNewton(const Map& forward, const double* target, double* solution, double tolerance) noexcept {
  using Jet = ceres::Jet<double, 2>;
  double x[2] = {target[0], target[1]};
  for (int it = 0; it < kInverseMaxIterations; ++it) {
    Jet in[2] = {Jet(x[0], 0), Jet(x[1], 1)};
    Jet out[2];
    forward(in, out);
    const double rx = out[0].a - target[0];
    const double ry = out[1].a - target[1];
    if (!std::isfinite(rx) || !std::isfinite(ry)) return false;
    // |r| <= tolerance, squared: std::hypot (which guards against overflow and underflow that cannot matter for a
    // comparison with a tolerance of 1e-16..1e-6) was ~3 % of a harness case.
    if (rx * rx + ry * ry <= tolerance * tolerance) {
      solution[0] = x[0];
      solution[1] = x[1];
      return true;
    }
    const double j00 = out[0].v[0], j01 = out[0].v[1], j10 = out[1].v[0], j11 = out[1].v[1];
    const double det = j00 * j11 - j01 * j10;
    if (!(std::abs(det) > 1e-12)) return false;
    x[0] -= (j11 * rx - j01 * ry) / det;
    x[1] -= (-j10 * rx + j00 * ry) / det;
  }
  return false;
}

}  // namespace topocal::model
