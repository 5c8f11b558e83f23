#pragma once
// The Cramer-Rao bound of a spot's centre in a raw image: the smallest standard deviation any unbiased estimator can
// reach, for the renderer's PSF spot (correct/spot_render.h, kPsf: a Gaussian PSF integrated over each pixel) and
// the noise model of docs/spot-noise.md.
//
//   mu_i(theta) = b + F E_u(c_i) E_v(r_i),  E_u(c) = Phi((c + 1/2 - u) / s) - Phi((c - 1/2 - u) / s)
//   var_i = read^2 + (mu_i - b) / gain + q,  q = 1/12 DN^2 for integer images (quantisation)
//   Fisher  I = sum_i grad mu_i grad mu_i^T / var_i   over theta = (F, u, v, s, b)   (Gaussian noise, var fixed)
//   CRB(u) = (I^-1)_uu,  CRB(v) = (I^-1)_vv
// All five parameters unknown: a detector knows neither the spot's flux, nor its width, nor the local background.
// Pixels within 6 sigma of the centre (beyond, the spot's signal is < 1e-8 of its peak).
#include <cmath>

#include <Eigen/Dense>

namespace topocal::correct::testing {

struct NoiseModel {
  double read_noise_dn = 0;
  double gain_e_per_dn = 0;  // 0: no shot noise
  double quantisation_var_dn2 = 1.0 / 12.0;
};

// Variances (px^2) of the centre's u and v at the bound; `peak_dn` the Gaussian's peak (as the renderer takes it).
inline Eigen::Vector2d CentreCrbPx2(double u, double v, double sigma_px, double peak_dn, const NoiseModel& noise) {
  const double flux = peak_dn * 2.0 * M_PI * sigma_px * sigma_px;
  const int half = static_cast<int>(std::ceil(6.0 * sigma_px)) + 1;
  const auto phi = [](double x) { return std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI); };
  const auto Phi = [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); };
  // E, dE/dcentre, dE/dsigma of one pixel row or column.
  const auto profile = [&](int c, double centre, double* e, double* dc, double* ds) {
    const double a = (c + 0.5 - centre) / sigma_px, b = (c - 0.5 - centre) / sigma_px;
    *e = Phi(a) - Phi(b);
    *dc = -(phi(a) - phi(b)) / sigma_px;
    *ds = -(phi(a) * a - phi(b) * b) / sigma_px;
  };
  Eigen::Matrix<double, 5, 5> fisher = Eigen::Matrix<double, 5, 5>::Zero();
  for (int r = static_cast<int>(std::floor(v)) - half; r <= static_cast<int>(std::ceil(v)) + half; ++r) {
    double ev, dvc, dvs;
    profile(r, v, &ev, &dvc, &dvs);
    for (int c = static_cast<int>(std::floor(u)) - half; c <= static_cast<int>(std::ceil(u)) + half; ++c) {
      double eu, duc, dus;
      profile(c, u, &eu, &duc, &dus);
      const double signal = flux * eu * ev;
      double var = noise.read_noise_dn * noise.read_noise_dn + noise.quantisation_var_dn2;
      if (noise.gain_e_per_dn > 0) var += signal / noise.gain_e_per_dn;
      Eigen::Matrix<double, 5, 1> g;
      g << eu * ev, flux * duc * ev, flux * eu * dvc, flux * (dus * ev + eu * dvs), 1.0;
      fisher += g * g.transpose() / var;
    }
  }
  const Eigen::Matrix<double, 5, 5> cov = fisher.inverse();
  return {cov(1, 1), cov(2, 2)};
}

}  // namespace topocal::correct::testing
