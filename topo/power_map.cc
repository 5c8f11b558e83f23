#include "topo/power_map.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/QR>
#include <fmt/format.h>

namespace topocal::topo {
namespace {

bool Fail(std::string* why, std::string message) {
  if (why) *why = std::move(message);
  return false;
}

}  // namespace

bool ComputePowerMaps(const SurfaceEvaluator& surface, const PowerMapOptions& o, PowerMaps* maps, std::string* why) {
  const auto sampler = [&surface](double theta, int n, const double* rho, double* f, double* df, double* d2f) {
    const double ct = std::cos(theta), st = std::sin(theta);
    for (int k = 0; k < n; ++k) {
      model::SurfaceDerivatives d;
      if (!surface(rho[k] * ct, rho[k] * st, &d)) return false;
      f[k] = d.z;
      df[k] = d.zx * ct + d.zy * st;
      d2f[k] = ct * ct * d.zxx + 2.0 * ct * st * d.zxy + st * st * d.zyy;
    }
    return true;
  };
  return ComputePowerMaps(sampler, o, maps, why);
}

bool ComputePowerMaps(const TaylorPolynomial& psi, const PowerMapOptions& o, PowerMaps* maps, std::string* why) {
  std::vector<double> g(psi.degree() + 1);
  const int top = psi.degree();
  const auto sampler = [&](double theta, int n, const double* rho, double* f, double* df, double* d2f) {
    psi.MeridianCoefficients(theta, g.data());
    // Horner for the value and both derivatives together, one degree at a time over all samples: the samples'
    // chains are independent, so they vectorise and overlap (each sample's operations as in a per-sample loop).
    for (int k = 0; k < n; ++k) f[k] = g[top], df[k] = 0, d2f[k] = 0;
    for (int d = top - 1; d >= 0; --d) {
      const double gd = g[d];
      for (int k = 0; k < n; ++k) {
        const double r = rho[k];
        d2f[k] = d2f[k] * r + 2.0 * df[k];
        df[k] = df[k] * r + f[k];
        f[k] = f[k] * r + gd;
      }
    }
    return true;
  };
  return ComputePowerMaps(sampler, o, maps, why);
}

bool ComputePowerMaps(const MeridianSampler& meridian, const PowerMapOptions& o, PowerMaps* maps, std::string* why) {
  const int K = o.radial_samples, M = o.meridians, P = o.meridian_polynomial_order;
  if (M < 1 || K < 1 || !(o.radius_mm > 0)) return Fail(why, "power map grid is empty");
  const bool fit = o.method == MeridianMethod::kPolynomialFit;
  if (fit && K < P + 1) return Fail(why, fmt::format("{} radial samples cannot fit an order-{} polynomial", K, P));
  // The Eq. 23 design matrix in normalised s = rho / R is the same for every meridian: factor it once.
  Eigen::MatrixXd A(K, P);
  for (int k = 0; k < K; ++k) {
    const double s = static_cast<double>(k + 1) / K;
    double sp = 1.0;
    for (int i = 0; i < P; ++i) A(k, i) = (sp *= s);
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr;
  if (fit) {
    qr.compute(A);
    if (qr.rank() < P) return Fail(why, "meridian polynomial fit is singular");
  }
  const double power_per_curvature = model::PowerFromCurvatureD(1.0, o.corneal_index, o.surrounding_index);  // Eq. 25

  maps->meridians = M;
  maps->radial_samples = K;
  maps->radius_mm = o.radius_mm;
  maps->axial_D.assign(static_cast<size_t>(M) * K, 0.0);
  maps->tangential_D.assign(static_cast<size_t>(M) * K, 0.0);
  Eigen::VectorXd f(K), d1s(K), d2s(K), rho(K);
  Eigen::ArrayXd g(K), root_g(K);  // 1 + F'^2 and its square root
  for (int k = 0; k < K; ++k) rho(k) = o.radius_mm * (k + 1) / K;
  for (int j = 0; j < M; ++j) {
    const double theta = 2.0 * M_PI * j / M;
    if (!meridian(theta, K, rho.data(), f.data(), d1s.data(), d2s.data())) {
      return Fail(why, fmt::format("surface undefined within rho = {:.3f} mm on the meridian at {:.1f} deg",
                                   o.radius_mm, theta * 180 / M_PI));
    }
    if (fit) {
      const Eigen::VectorXd c = qr.solve(f);  // coefficients of s^i, i = 1..P
      for (int k = 0; k < K; ++k) {
        const double s = static_cast<double>(k + 1) / K;
        double d1 = 0, d2 = 0, sp = 1.0;  // sp = s^(i-1); d/drho = (1/R) d/ds
        for (int i = 1; i <= P; ++i) {
          d1 += i * c(i - 1) * sp;
          if (i >= 2) d2 += i * (i - 1) * c(i - 1) * sp / s;
          sp *= s;
        }
        d1s(k) = d1 / o.radius_mm;
        d2s(k) = d2 / (o.radius_mm * o.radius_mm);
      }
    }
    Eigen::Map<Eigen::ArrayXd> axial(maps->axial_D.data() + static_cast<size_t>(j) * K, K);
    Eigen::Map<Eigen::ArrayXd> tangential(maps->tangential_D.data() + static_cast<size_t>(j) * K, K);
    // As Eigen array expressions, so that the square roots and divisions run two samples at a time (issue 15: the
    // scalar loop did not vectorise, as std::sqrt may set errno); each element is the same correctly rounded
    // operations in the same order as the per-sample formulas, so the same bits.
    const auto d1 = d1s.array(), d2 = d2s.array();
    g = 1.0 + d1 * d1;
    root_g = g.sqrt();
    axial = d1 / (rho.array() * root_g) * power_per_curvature;  // Eq. 24, 25
    tangential = d2 / (g * root_g) * power_per_curvature;
    for (int k = 0; k < K; ++k) {
      // A non-finite curvature is non-finite times a finite power_per_curvature: the same test as on ka, km.
      if (!std::isfinite(axial[k]) || !std::isfinite(tangential[k])) return Fail(why, "curvature is not finite");
    }
  }
  const auto [amin, amax] = std::minmax_element(maps->axial_D.begin(), maps->axial_D.end());
  const auto [tmin, tmax] = std::minmax_element(maps->tangential_D.begin(), maps->tangential_D.end());
  maps->pv_axial_D = *amax - *amin;       // Eq. 28b
  maps->pv_tangential_D = *tmax - *tmin;  // Eq. 28a
  return true;
}

double MeanAxialPowerD(const PowerMaps& maps, double radius_mm) {
  double sum = 0, weight = 0;
  for (int j = 0; j < maps.meridians; ++j) {
    for (int k = 0; k < maps.radial_samples; ++k) {
      const double rho = maps.RhoMm(k);
      if (rho > radius_mm) break;
      sum += rho * maps.axial_D[static_cast<size_t>(j * maps.radial_samples + k)];
      weight += rho;
    }
  }
  return weight > 0 ? sum / weight : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace topocal::topo
