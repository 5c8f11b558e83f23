#include "topo/taylor_polynomial.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/QR>

namespace topocal::topo {
namespace {
constexpr int kMaxDegree = 14;  // ReconstructionSettings caps taylor_degree at 14; powers tables are sized for it

// pu[i] = u^i, pv[i] = v^i for i = 0..degree.
void Powers(double u, double v, int degree, double* pu, double* pv) {
  pu[0] = pv[0] = 1.0;
  for (int i = 1; i <= degree; ++i) {
    pu[i] = pu[i - 1] * u;
    pv[i] = pv[i - 1] * v;
  }
}

}  // namespace

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

// Both evaluations below are nested Horner schemes: Psi = sum_a u^a Q_a(v), Q_a(v) = sum_b c(a, b) v^b, with
// c(a, b) the coefficient of u^a v^b (index d (d + 1) / 2 + b for d = a + b, the term order of the header). The
// inner scheme carries Q_a and its v-derivatives, the outer one Psi and its u-derivatives; about 2 (value and
// gradient) or 3 (with the Hessian) multiply-adds per term, no table of powers and no branch per term. The plain
// sum over monomials they replace is kept in tests/topo/taylor_polynomial_test.cc as the reference (agreement
// ~1e-15 relative to the sum of the terms' magnitudes).
void TaylorPolynomial::ValueAndGradient(double x_mm, double y_mm, double* z, double* zx, double* zy) const {
  // The ray intersections and consistency checks need no Hessian: half the work of Derivatives().
  const double u = x_mm / norm_radius_mm_, v = y_mm / norm_radius_mm_;
  const double* c = coefficients_.data();
  const int n = degree_;
  double p = 0, pu = 0, pv = 0;
  for (int a = n; a >= 0; --a) {
    // Q_a(v) and Q_a'(v), from the highest power of v (b = n - a) down.
    int d = n;  // degree of the term (a, b) with b = d - a
    double q = c[d * (d + 1) / 2 + (d - a)], dq = 0;
    for (d = n - 1; d >= a; --d) {
      dq = dq * v + q;
      q = q * v + c[d * (d + 1) / 2 + (d - a)];
    }
    pu = pu * u + p;
    p = p * u + q;
    pv = pv * u + dq;
  }
  *z = p;
  *zx = pu / norm_radius_mm_;
  *zy = pv / norm_radius_mm_;
}

void TaylorPolynomial::Derivatives(double x_mm, double y_mm, double* z, double* zx, double* zy, double* zxx,
                                   double* zxy, double* zyy) const {
  const double inv = 1.0 / norm_radius_mm_;
  const double u = x_mm / norm_radius_mm_, v = y_mm / norm_radius_mm_;
  const double* c = coefficients_.data();
  const int n = degree_;
  double p = 0, pu = 0, puu = 0, pv = 0, puv = 0, pvv = 0;
  for (int a = n; a >= 0; --a) {
    int d = n;
    double q = c[d * (d + 1) / 2 + (d - a)], dq = 0, ddq = 0;
    for (d = n - 1; d >= a; --d) {
      ddq = ddq * v + 2.0 * dq;
      dq = dq * v + q;
      q = q * v + c[d * (d + 1) / 2 + (d - a)];
    }
    puu = puu * u + 2.0 * pu;
    pu = pu * u + p;
    p = p * u + q;
    puv = puv * u + pv;
    pv = pv * u + dq;
    pvv = pvv * u + ddq;
  }
  *z = p;
  *zx = pu * inv;
  *zy = pv * inv;
  *zxx = puu * inv * inv;
  *zxy = puv * inv * inv;
  *zyy = pvv * inv * inv;
}

void TaylorPolynomial::MeridianCoefficients(double theta_rad, double* g) const {
  const double c = std::cos(theta_rad) / norm_radius_mm_, s = std::sin(theta_rad) / norm_radius_mm_;
  double pc[kMaxDegree + 1], ps[kMaxDegree + 1];
  Powers(c, s, degree_, pc, ps);
  for (int d = 0; d <= degree_; ++d) g[d] = 0.0;
  for (int k = 0; k < terms(); ++k) {
    const auto [a, b] = exponents_[k];
    g[a + b] += coefficients_[k] * pc[a] * ps[b];
  }
}

void TaylorPolynomial::GradientRows(double x_mm, double y_mm, double* row_x, double* row_y) const {
  const double u = x_mm / norm_radius_mm_, v = y_mm / norm_radius_mm_;
  double pu[kMaxDegree + 1], pv[kMaxDegree + 1];
  Powers(u, v, degree_, pu, pv);
  const double inv = 1.0 / norm_radius_mm_;
  for (int k = 1; k < terms(); ++k) {
    const auto [a, b] = exponents_[k];
    row_x[k - 1] = a >= 1 ? a * pu[a - 1] * pv[b] * inv : 0.0;
    row_y[k - 1] = b >= 1 ? b * pu[a] * pv[b - 1] * inv : 0.0;
  }
}

namespace {

// The design matrix of the gradient fit: rows 2i and 2i + 1 are GradientRows at point i. Filled column by column
// (A is column-major; writing it row by row touched a cache line per element) from tables of the points' powers,
// one table per power so that each column is one sequential pass: the same products in the same order as
// GradientRows, so the same matrix bit for bit (tests/topo/taylor_polynomial_test.cc).
void BuildDesign(const TaylorPolynomial& poly, const std::vector<Eigen::Vector2d>& points_mm,
                 const std::vector<Eigen::Vector2d>& slopes, Eigen::MatrixXd* A, Eigen::VectorXd* rhs) {
  const int n = static_cast<int>(points_mm.size());
  const int unknowns = poly.terms() - 1;
  const int degree = poly.degree();
  const double norm = poly.norm_radius_mm();
  A->resize(2 * n, unknowns);
  rhs->resize(2 * n);
  const auto at = [n](int power, int i) { return static_cast<size_t>(power) * n + i; };
  std::vector<double> pu(static_cast<size_t>(degree + 1) * n), pv(pu.size());
  for (int i = 0; i < n; ++i) {
    double u[kMaxDegree + 1], v[kMaxDegree + 1];
    Powers(points_mm[i].x() / norm, points_mm[i].y() / norm, degree, u, v);
    for (int p = 0; p <= degree; ++p) {
      pu[at(p, i)] = u[p];
      pv[at(p, i)] = v[p];
    }
    (*rhs)(2 * i) = slopes[i].x();
    (*rhs)(2 * i + 1) = slopes[i].y();
  }
  const double inv = 1.0 / norm;
  for (int k = 1; k < poly.terms(); ++k) {
    const auto [a, b] = poly.Exponents(k);
    double* col = A->col(k - 1).data();
    for (int i = 0; i < n; ++i) {
      col[2 * i] = a >= 1 ? a * pu[at(a - 1, i)] * pv[at(b, i)] * inv : 0.0;
      col[2 * i + 1] = b >= 1 ? b * pu[at(a, i)] * pv[at(b - 1, i)] * inv : 0.0;
    }
  }
}

// Preconditioned CGLS on min |A x - b| with x = R^-1 y, warm-started at x. True when the preconditioned normal
// residual |R^-T A^T (b - A x)| falls below `tolerance` times its value at x = 0.
bool PreconditionedCgls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::MatrixXd& R,
                        Eigen::VectorXd* x) {
  // 1e-14: the normal residual of a QR solution in double on this problem is ~1e-15 relative; CGLS stops close
  // above. (1e-13 left a cold first fit from the Cholesky factor 4e-11 from the QR solution; 1e-14 took as many
  // iterations over the paper sweep and 40 harness cases, 2-16, median 7, never the budget; issue 15.)
  constexpr double kTolerance = 1e-14;
  constexpr int kMaxIterations = 25;
  const auto Rt = R.triangularView<Eigen::Upper>();
  Eigen::VectorXd r = b - A * (*x);
  Eigen::VectorXd s = Rt.transpose().solve(A.transpose() * r);
  const double reference = Rt.transpose().solve(A.transpose() * b).norm();
  Eigen::VectorXd p = s;
  double gamma = s.squaredNorm();
  for (int it = 0; it < kMaxIterations; ++it) {
    if (std::sqrt(gamma) <= kTolerance * reference) return true;
    const Eigen::VectorXd rp = Rt.solve(p);
    const Eigen::VectorXd q = A * rp;
    const double qq = q.squaredNorm();
    if (!(qq > 0)) return false;
    const double alpha = gamma / qq;
    *x += alpha * rp;
    r -= alpha * q;
    s = Rt.transpose().solve(A.transpose() * r);
    const double gamma_next = s.squaredNorm();
    p = s + (gamma_next / gamma) * p;
    gamma = gamma_next;
  }
  return std::sqrt(gamma) <= kTolerance * reference;
}

bool SolveByQr(const Eigen::MatrixXd& A, const Eigen::VectorXd& rhs, Eigen::VectorXd* x, Eigen::MatrixXd* r_out) {
  // Blocked Householder QR (no pivoting: the monomial columns in normalised coordinates are never exactly
  // dependent once 2n >= N - 1 points are spread over the disc); rank is checked on R's diagonal.
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(A);
  const auto diag = qr.matrixQR().diagonal().cwiseAbs();
  if (!(diag.minCoeff() > 1e-10 * diag.maxCoeff())) return false;
  *x = qr.solve(rhs);
  if (r_out) *r_out = qr.matrixQR().topRows(A.cols()).triangularView<Eigen::Upper>();
  return x->allFinite();
}

// A^T A of the design matrix (BuildDesign) from the moments of the points, M(p, q) = sum_i u_i^p v_i^q: the
// entry of the terms u^a v^b and u^c v^d is (a c M(a+c-2, b+d) + b d M(a+c, b+d-2)) / R^2 (the x rows and the
// y rows of the gradient). The moments up to degree 2D - 2 are ~150 sums over the points, against the 2 m n^2 of
// forming A^T A from A (whose blocked product also packed A into fresh buffers: page faults). Lower triangle only.
void NormalMatrixFromMoments(const TaylorPolynomial& poly, const std::vector<Eigen::Vector2d>& points_mm,
                             Eigen::MatrixXd* normal) {
  constexpr int kMaxMoment = 2 * kMaxDegree - 2;
  const int top = 2 * poly.degree() - 2;
  const double norm = poly.norm_radius_mm();
  double moments[kMaxMoment + 1][kMaxMoment + 1] = {};
  for (const auto& p : points_mm) {
    double pu[kMaxMoment + 1], pv[kMaxMoment + 1];
    Powers(p.x() / norm, p.y() / norm, top, pu, pv);
    for (int a = 0; a <= top; ++a) {
      for (int b = 0; a + b <= top; ++b) moments[a][b] += pu[a] * pv[b];
    }
  }
  const int unknowns = poly.terms() - 1;
  const double inv2 = 1.0 / (norm * norm);
  normal->resize(unknowns, unknowns);
  for (int k = 1; k <= unknowns; ++k) {
    const auto [a, b] = poly.Exponents(k);
    for (int l = 1; l <= k; ++l) {
      const auto [c, d] = poly.Exponents(l);
      double sum = 0;
      if (a >= 1 && c >= 1) sum += a * c * moments[a + c - 2][b + d];
      if (b >= 1 && d >= 1) sum += b * d * moments[a + c][b + d - 2];
      (*normal)(k - 1, l - 1) = sum * inv2;
    }
  }
}

// The factor R (R^T R = A^T A) from the Cholesky factorisation of the normal matrix A^T A. Far less work than the
// Householder QR of A and no copy of A (the QR's 1248 x 64 copy was a fresh 640 KB block per reconstruction: page
// faults and a memset). R only preconditions CGLS, which then iterates to the least-squares solution itself, so
// the squared condition number of the normal equations costs iterations, not accuracy: with the polynomial
// normalised on the data radius cond(A) is ~4e3 (degree 10 over a disc of 600 points:
// tests/topo/power_map_test.cc), so A R^-1 is orthonormal to ~1e-8 and CGLS reaches the QR solution to ~5e-14
// relative in a few iterations from a cold start (the normal equations alone: ~1e-10). False (the caller falls
// back to QR) when the factorisation fails or R's diagonal spans more than 1e6 (A^T A's condition number beyond
// ~1e12: the preconditioner would be too far from A's own R to trust).
bool FactorNormalEquations(const TaylorPolynomial& poly, const std::vector<Eigen::Vector2d>& points_mm,
                           Eigen::MatrixXd* normal, Eigen::MatrixXd* r) {
  NormalMatrixFromMoments(poly, points_mm, normal);
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(*normal);  // in place: L in the lower triangle
  if (llt.info() != Eigen::Success) return false;
  const auto diag = normal->diagonal().cwiseAbs();
  if (!(diag.minCoeff() > 1e-6 * diag.maxCoeff())) return false;
  *r = normal->transpose().triangularView<Eigen::Upper>();
  return r->allFinite();
}

GradientFit Finish(const Eigen::MatrixXd& A, const Eigen::VectorXd& rhs, const Eigen::VectorXd& b,
                   double z_at_origin_mm, TaylorPolynomial* poly) {
  GradientFit fit;
  const int unknowns = static_cast<int>(b.size());
  poly->coefficients().tail(unknowns) = b;
  // Psi(0, 0) is the piston alone (every other monomial vanishes at the origin).
  poly->coefficients()(0) = z_at_origin_mm;
  fit.rms_slope_residual = std::sqrt((A * b - rhs).squaredNorm() / A.rows());
  fit.ok = true;
  return fit;
}

}  // namespace

GradientFit GradientFitter::Fit(const std::vector<Eigen::Vector2d>& points_mm,
                                const std::vector<Eigen::Vector2d>& slopes, double z_at_origin_mm,
                                TaylorPolynomial* poly) {
  const int unknowns = poly->terms() - 1;
  if (2 * static_cast<int>(points_mm.size()) < unknowns || slopes.size() != points_mm.size()) return {};
  BuildDesign(*poly, points_mm, slopes, &a_, &rhs_);
  Eigen::VectorXd x = poly->coefficients().tail(unknowns);
  if (started_ && r_.rows() == unknowns && PreconditionedCgls(a_, rhs_, r_, &x)) {
    return Finish(a_, rhs_, x, z_at_origin_mm, poly);
  }
  started_ = false;
  ++factorizations_;
  // The factor of these points: from the normal equations (cheap), by QR when they are too ill-conditioned to
  // serve or CGLS does not converge with their factor.
  x = poly->coefficients().tail(unknowns);
  if (FactorNormalEquations(*poly, points_mm, &normal_, &r_) && PreconditionedCgls(a_, rhs_, r_, &x)) {
    return Finish(a_, rhs_, x, z_at_origin_mm, poly);
  }
  x = poly->coefficients().tail(unknowns);
  if (!SolveByQr(a_, rhs_, &x, &r_)) {
    r_.resize(0, 0);
    return {};
  }
  return Finish(a_, rhs_, x, z_at_origin_mm, poly);
}

GradientFit FitGradient(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes,
                        double z_at_origin_mm, TaylorPolynomial* poly) {
  const int unknowns = poly->terms() - 1;
  if (2 * static_cast<int>(points_mm.size()) < unknowns || slopes.size() != points_mm.size()) return {};
  Eigen::MatrixXd A;
  Eigen::VectorXd rhs, x;
  BuildDesign(*poly, points_mm, slopes, &A, &rhs);
  if (!SolveByQr(A, rhs, &x, nullptr)) return {};
  return Finish(A, rhs, x, z_at_origin_mm, poly);
}

}  // namespace topocal::topo
