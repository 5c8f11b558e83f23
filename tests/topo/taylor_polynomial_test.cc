// The Horner evaluation of Psi (topo/taylor_polynomial.cc) against the plain sum over monomials it replaced, kept
// here as the reference.
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/QR>
#include <gtest/gtest.h>

#include "topo/taylor_polynomial.h"

namespace topocal::topo {
namespace {

struct Reference {
  double z = 0, zx = 0, zy = 0, zxx = 0, zxy = 0, zyy = 0;
  double magnitude = 0;  // sum of |c_k psi_k| and of the derivatives' terms: the scale rounding errors are relative to
};

// The earlier formula: sum_k c_k u^a v^b and its derivatives term by term (powers from a table).
Reference SumOfMonomials(const TaylorPolynomial& p, double x_mm, double y_mm) {
  const double r = p.norm_radius_mm(), u = x_mm / r, v = y_mm / r;
  Reference out;
  for (int k = 0; k < p.terms(); ++k) {
    const auto [a, b] = p.Exponents(k);
    const double c = p.coefficients()[k];
    const auto pw = [](double t, int e) { return e < 0 ? 0.0 : std::pow(t, e); };
    const double terms[6] = {c * pw(u, a) * pw(v, b),
                             c * a * pw(u, a - 1) * pw(v, b) / r,
                             c * b * pw(u, a) * pw(v, b - 1) / r,
                             c * a * (a - 1) * pw(u, a - 2) * pw(v, b) / (r * r),
                             c * a * b * pw(u, a - 1) * pw(v, b - 1) / (r * r),
                             c * b * (b - 1) * pw(u, a) * pw(v, b - 2) / (r * r)};
    out.z += terms[0];
    out.zx += terms[1];
    out.zy += terms[2];
    out.zxx += terms[3];
    out.zxy += terms[4];
    out.zyy += terms[5];
    for (double t : terms) out.magnitude += std::abs(t);
  }
  return out;
}

TEST(TaylorPolynomial, HornerMatchesTheSumOfMonomials) {
  // 1e-12 of the terms' magnitudes (the bound); both evaluations are ~1e-16 relative to that scale, so
  // anything above 1e-12 is a wrong index or exponent, not rounding. Measured 2026-12-01: largest 1.3e-15.
  constexpr double kRelTol = 1e-12;
  constexpr double kRegressionRelTol = 1e-14;
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> coefficient(-1.0, 1.0), position(-6.0, 6.0);
  double worst = 0;
  for (int degree : {0, 1, 2, 5, 9, 10, 14}) {
    TaylorPolynomial p(degree, 5.3);
    // Coefficients falling with the degree as a cornea's do (sag ~ mm, higher orders ~ um), both signs.
    for (int k = 0; k < p.terms(); ++k) {
      const auto [a, b] = p.Exponents(k);
      p.coefficients()[k] = coefficient(rng) * std::pow(0.3, a + b);
    }
    for (int i = 0; i < 200; ++i) {
      const double x = position(rng), y = position(rng);
      const Reference ref = SumOfMonomials(p, x, y);
      double z, zx, zy, hz, hzx, hzy, hzxx, hzxy, hzyy;
      p.ValueAndGradient(x, y, &z, &zx, &zy);
      p.Derivatives(x, y, &hz, &hzx, &hzy, &hzxx, &hzxy, &hzyy);
      const double got[] = {z, zx, zy, hz, hzx, hzy, hzxx, hzxy, hzyy};
      const double want[] = {ref.z, ref.zx, ref.zy, ref.z, ref.zx, ref.zy, ref.zxx, ref.zxy, ref.zyy};
      for (int j = 0; j < 9; ++j) {
        const double rel = std::abs(got[j] - want[j]) / ref.magnitude;
        worst = std::max(worst, rel);
        ASSERT_LE(rel, kRelTol) << "degree " << degree << " at (" << x << ", " << y << "), output " << j;
      }
      EXPECT_EQ(p.Value(x, y), z);
    }
  }
  EXPECT_LE(worst, kRegressionRelTol);
}

// The batched evaluation (the reconstruction's ray intersections) runs eight points at once, then pairs,
// then single points: each must be the single-point evaluation bit for bit, whichever group it falls in.
TEST(TaylorPolynomial, ValueAndGradientManyIsTheSinglePointEvaluationBitForBit) {
  std::mt19937 rng(16);
  std::uniform_real_distribution<double> coefficient(-1.0, 1.0), position(-6.0, 6.0);
  for (int degree : {0, 1, 3, 10, 14}) {
    TaylorPolynomial p(degree, 5.3);
    for (int k = 0; k < p.terms(); ++k) p.coefficients()[k] = coefficient(rng);
    for (int count : {0, 1, 4, 7, 101}) {
      std::vector<double> x(count), y(count), z(count), zx(count), zy(count);
      for (int i = 0; i < count; ++i) x[i] = position(rng), y[i] = position(rng);
      p.ValueAndGradientMany(count, x.data(), y.data(), z.data(), zx.data(), zy.data());
      for (int i = 0; i < count; ++i) {
        double z1, zx1, zy1;
        p.ValueAndGradient(x[i], y[i], &z1, &zx1, &zy1);
        ASSERT_EQ(z[i], z1) << "degree " << degree << ", point " << i << " of " << count;
        ASSERT_EQ(zx[i], zx1) << "degree " << degree << ", point " << i << " of " << count;
        ASSERT_EQ(zy[i], zy1) << "degree " << degree << ", point " << i << " of " << count;
      }
    }
  }
}

// The gradient fit's design matrix is built column by column from tables of powers; before, row by row
// from GradientRows. Same products, same order: the fit must be the one a QR of the GradientRows matrix gives, bit
// for bit.
TEST(TaylorPolynomial, GradientFitIsTheQrSolutionOfTheGradientRowsBitForBit) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> position(-4.5, 4.5), slope(-0.6, 0.6);
  std::vector<Eigen::Vector2d> points, slopes;
  for (int i = 0; i < 300; ++i) {
    points.emplace_back(position(rng), position(rng));
    slopes.emplace_back(slope(rng), slope(rng));
  }
  TaylorPolynomial fitted(10, 5.0);
  ASSERT_TRUE(FitGradient(points, slopes, 0.25, &fitted).ok);
  const TaylorPolynomial reference_poly(10, 5.0);
  const int unknowns = reference_poly.terms() - 1;
  Eigen::MatrixXd A(2 * points.size(), unknowns);
  Eigen::VectorXd rhs(2 * points.size());
  std::vector<double> rx(unknowns), ry(unknowns);
  for (size_t i = 0; i < points.size(); ++i) {
    reference_poly.GradientRows(points[i].x(), points[i].y(), rx.data(), ry.data());
    for (int k = 0; k < unknowns; ++k) {
      A(2 * i, k) = rx[k];
      A(2 * i + 1, k) = ry[k];
    }
    rhs(2 * i) = slopes[i].x();
    rhs(2 * i + 1) = slopes[i].y();
  }
  const Eigen::VectorXd want = Eigen::HouseholderQR<Eigen::MatrixXd>(A).solve(rhs);
  for (int k = 0; k < unknowns; ++k) EXPECT_EQ(fitted.coefficients()[k + 1], want[k]) << "term " << k + 1;
  EXPECT_EQ(fitted.coefficients()[0], 0.25);
}

}  // namespace
}  // namespace topocal::topo
