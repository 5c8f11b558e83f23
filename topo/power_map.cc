#include "topo/power_map.h"

#include <fmt/format.h>

#include <Eigen/Core>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

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
    // Horner for the value and both derivatives together, 8 samples at a time in registers (the samples' chains
    // are independent, so they vectorise and overlap), then one at a time; each sample's operations as in a
    // per-sample loop. Over all the samples one degree at a time, as before, every statement was a pass through
    // memory (3 loads and a store for 2-3 operations): the same numbers, bit for bit, at about half the time.
    // Eigen arrays, because the compiler cannot vectorise the loop over raw pointers that may alias.
    const auto samples = [&](auto block, int k) {
      using Block = Eigen::Array<double, decltype(block)::value, 1>;
      const Block r = Eigen::Map<const Block>(rho + k);
      Block fa = Block::Constant(g[top]), dfa = Block::Zero(), d2fa = Block::Zero();
      for (int d = top - 1; d >= 0; --d) {
        d2fa = d2fa * r + 2.0 * dfa;
        dfa = dfa * r + fa;
        fa = fa * r + g[d];
      }
      Eigen::Map<Block>(f + k) = fa;
      Eigen::Map<Block>(df + k) = dfa;
      Eigen::Map<Block>(d2f + k) = d2fa;
    };
    int k = 0;
    for (; k + 8 <= n; k += 8) samples(std::integral_constant<int, 8>(), k);
    for (; k < n; ++k) samples(std::integral_constant<int, 1>(), k);
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
  Eigen::ArrayXd g(K), sqrt_g(K);
  double axial_min = INFINITY, axial_max = -INFINITY, tangential_min = INFINITY, tangential_max = -INFINITY;
  for (int k = 0; k < K; ++k) rho(k) = o.radius_mm * (k + 1) / K;
  // A point-symmetric surface: meridian j + M/2 has meridian j's profile, so its powers are the same numbers
  // (copied below, after the first half; the extremes are those of the first half).
  const int computed = o.point_symmetric && M % 2 == 0 ? M / 2 : M;
  for (int j = 0; j < computed; ++j) {
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
    // Eigen's array sqrt and division are the packed IEEE instructions (std::sqrt in a loop is not vectorised:
    // it may set errno), with the same correctly rounded results as the scalar ones.
    g = 1.0 + d1s.array() * d1s.array();
    sqrt_g = g.sqrt();
    axial = d1s.array() / (rho.array() * sqrt_g) * power_per_curvature;  // Eq. 24, 25
    tangential = d2s.array() / (g * sqrt_g) * power_per_curvature;
    // A non-finite curvature is non-finite times a finite power_per_curvature: the same test as on ka, km. x * 0
    // is 0 exactly when x is finite (NaN for an infinity or a NaN); a packed comparison, unlike std::isfinite.
    if (!((axial * 0.0 == 0.0).all() && (tangential * 0.0 == 0.0).all())) {
      return Fail(why, "curvature is not finite");
    }
    // The extremes of the maps, meridian by meridian while it is in cache (packed min and max: the same values).
    axial_min = std::min(axial_min, axial.minCoeff());
    axial_max = std::max(axial_max, axial.maxCoeff());
    tangential_min = std::min(tangential_min, tangential.minCoeff());
    tangential_max = std::max(tangential_max, tangential.maxCoeff());
  }
  const size_t half = static_cast<size_t>(computed) * K;
  if (computed < M) {
    std::copy_n(maps->axial_D.begin(), half, maps->axial_D.begin() + half);
    std::copy_n(maps->tangential_D.begin(), half, maps->tangential_D.begin() + half);
  }
  maps->pv_axial_D = axial_max - axial_min;                 // Eq. 28b
  maps->pv_tangential_D = tangential_max - tangential_min;  // Eq. 28a
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
