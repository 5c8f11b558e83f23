#include "topo/taylor_polynomial.h"

#include <cmath>

#include <Eigen/QR>

namespace topocal::topo {
namespace {
constexpr int kMaxDegree = 14;  // ReconstructionSettings caps taylor_degree at 14; powers tables are sized for it
}

TaylorPolynomial::TaylorPolynomial(int degree, double norm_radius_mm)
    : degree_(degree), norm_radius_mm_(norm_radius_mm), coefficients_(Eigen::VectorXd::Zero(TermCount(degree))) {
  exponents_.reserve(TermCount(degree));
  for (int d = 0; d <= degree; ++d) {
    for (int j = 0; j <= d; ++j) exponents_.emplace_back(d - j, j);
  }
}

double TaylorPolynomial::Value(double x_mm, double y_mm) const {
  double z, zx, zy;
  ValueAndGradient(x_mm, y_mm, &z, &zx, &zy);
  return z;
}

void TaylorPolynomial::ValueAndGradient(double x_mm, double y_mm, double* z, double* zx, double* zy) const {
  double zxx, zxy, zyy;
  Derivatives(x_mm, y_mm, z, zx, zy, &zxx, &zxy, &zyy);
}

void TaylorPolynomial::Derivatives(double x_mm, double y_mm, double* z, double* zx, double* zy, double* zxx,
                                   double* zxy, double* zyy) const {
  const double u = x_mm / norm_radius_mm_, v = y_mm / norm_radius_mm_;
  double pu[kMaxDegree + 1], pv[kMaxDegree + 1];
  pu[0] = pv[0] = 1.0;
  for (int i = 1; i <= degree_; ++i) {
    pu[i] = pu[i - 1] * u;
    pv[i] = pv[i - 1] * v;
  }
  double s = 0, su = 0, sv = 0, suu = 0, suv = 0, svv = 0;
  for (int k = 0; k < terms(); ++k) {
    const auto [a, b] = exponents_[k];
    const double c = coefficients_[k];
    s += c * pu[a] * pv[b];
    if (a >= 1) su += c * a * pu[a - 1] * pv[b];
    if (b >= 1) sv += c * b * pu[a] * pv[b - 1];
    if (a >= 2) suu += c * a * (a - 1) * pu[a - 2] * pv[b];
    if (a >= 1 && b >= 1) suv += c * a * b * pu[a - 1] * pv[b - 1];
    if (b >= 2) svv += c * b * (b - 1) * pu[a] * pv[b - 2];
  }
  const double inv = 1.0 / norm_radius_mm_;
  *z = s;
  *zx = su * inv;
  *zy = sv * inv;
  *zxx = suu * inv * inv;
  *zxy = suv * inv * inv;
  *zyy = svv * inv * inv;
}

void TaylorPolynomial::GradientRows(double x_mm, double y_mm, double* row_x, double* row_y) const {
  const double u = x_mm / norm_radius_mm_, v = y_mm / norm_radius_mm_;
  double pu[kMaxDegree + 1], pv[kMaxDegree + 1];
  pu[0] = pv[0] = 1.0;
  for (int i = 1; i <= degree_; ++i) {
    pu[i] = pu[i - 1] * u;
    pv[i] = pv[i - 1] * v;
  }
  const double inv = 1.0 / norm_radius_mm_;
  for (int k = 1; k < terms(); ++k) {
    const auto [a, b] = exponents_[k];
    row_x[k - 1] = a >= 1 ? a * pu[a - 1] * pv[b] * inv : 0.0;
    row_y[k - 1] = b >= 1 ? b * pu[a] * pv[b - 1] * inv : 0.0;
  }
}

GradientFit FitGradient(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes,
                        double z_at_origin_mm, TaylorPolynomial* poly) {
  GradientFit fit;
  const int n = static_cast<int>(points_mm.size());
  const int unknowns = poly->terms() - 1;
  if (2 * n < unknowns || slopes.size() != points_mm.size()) return fit;
  Eigen::MatrixXd A(2 * n, unknowns);
  Eigen::VectorXd rhs(2 * n);
  std::vector<double> rx(unknowns), ry(unknowns);
  for (int i = 0; i < n; ++i) {
    poly->GradientRows(points_mm[i].x(), points_mm[i].y(), rx.data(), ry.data());
    A.row(2 * i) = Eigen::Map<const Eigen::RowVectorXd>(rx.data(), unknowns);
    A.row(2 * i + 1) = Eigen::Map<const Eigen::RowVectorXd>(ry.data(), unknowns);
    rhs(2 * i) = slopes[i].x();
    rhs(2 * i + 1) = slopes[i].y();
  }
  // Blocked Householder QR (no pivoting: the monomial columns in normalised coordinates are never exactly
  // dependent once 2n >= N - 1 points are spread over the disc); rank is checked on R's diagonal.
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(A);
  const auto diag = qr.matrixQR().diagonal().cwiseAbs();
  if (!(diag.minCoeff() > 1e-10 * diag.maxCoeff())) return fit;
  const Eigen::VectorXd b = qr.solve(rhs);
  if (!b.allFinite()) return fit;
  poly->coefficients().tail(unknowns) = b;
  poly->coefficients()(0) = 0.0;
  // Psi(0, 0) is the piston alone (every other monomial vanishes at the origin).
  poly->coefficients()(0) = z_at_origin_mm;
  fit.rms_slope_residual = std::sqrt((A * b - rhs).squaredNorm() / (2 * n));
  fit.ok = true;
  return fit;
}

}  // namespace topocal::topo
