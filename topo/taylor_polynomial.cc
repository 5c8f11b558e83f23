#include "topo/taylor_polynomial.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <type_traits>

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

void TaylorPolynomial::ValueAndGradientMany(int count, const double* x_mm, const double* y_mm, double* z,
                                            double* zx, double* zy) const {
  // The scheme of ValueAndGradient, statement for statement, on W points at once (bit-identical to it): one point's
  // Horner chain is a sequence of dependent multiplies and adds (latency-bound); as Eigen fixed-size arrays, W = 8
  // points are four packed (two-double) chains per statement, which fill the pipeline, where scalar code of four
  // chains left it half idle.
  const double* c = coefficients_.data();
  const int n = degree_;
  const double radius = norm_radius_mm_;
  const auto block = [&]<int W>(int i) {
    using A = Eigen::Array<double, W, 1>;
    const A u = Eigen::Map<const A>(x_mm + i) / radius;
    const A v = Eigen::Map<const A>(y_mm + i) / radius;
    A p = A::Zero(), pu = A::Zero(), pv = A::Zero(), q, dq;
    for (int a = n; a >= 0; --a) {
      q.setConstant(c[n * (n + 1) / 2 + (n - a)]);
      dq.setZero();
      for (int d = n - 1; d >= a; --d) {
        const double cd = c[d * (d + 1) / 2 + (d - a)];
        dq = dq * v + q;
        q = q * v + cd;
      }
      pu = pu * u + p;
      p = p * u + q;
      pv = pv * u + dq;
    }
    Eigen::Map<A>(z + i) = p;
    Eigen::Map<A>(zx + i) = pu / radius;
    Eigen::Map<A>(zy + i) = pv / radius;
  };
  int i = 0;
  for (; i + 8 <= count; i += 8) block.template operator()<8>(i);
  for (; i + 2 <= count; i += 2) block.template operator()<2>(i);
  for (; i < count; ++i) ValueAndGradient(x_mm[i], y_mm[i], z + i, zx + i, zy + i);
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

// The gradient fit without its design matrix. The rows of A are the gradients of the monomials, so
// every product CGLS needs is a product with the table T of the monomials of degree <= D - 1 at the points
// (T(i, j) = u_i^p v_i^q, j the term index of u^p v^q): A x is the polynomial's gradient, (T gx, T gy) with gx, gy
// the coefficients of d Psi / dx and d Psi / dy, and A^T r gathers (T^T r_x, T^T r_y) back onto the terms. T has
// half as many entries as A and is built column by column from its neighbours (one multiplication per entry, no
// branch); filling A every pass was 14 % of the paper sweep. The slopes are columns (S_x, S_y) of an n x 2 matrix.
using TermMap = std::vector<internal::GradientTerm>;
// CGLS vectors.
struct CglsWork {
  Eigen::MatrixXd r, q, g, h;  // n x 2 residual and product, m x 2 gradient coefficients and gathered sums
  Eigen::VectorXd s, p, rp;
};

// The fit's buffers, one set per thread, kept from one fit to the next: the basis table alone is 270 KB for the
// paper's 624 spots, and a fresh block of that size comes from mmap, its pages faulted in on every reconstruction
// (~20 us per page on the development VM: 0.9 ms per reconstruction, measured). A fit does not call another, so
// one set per thread serves every fitter.
struct FitScratch {
  Eigen::MatrixXd basis;   // n x m: the monomials u^p v^q, p + q <= D - 1, at the points
  Eigen::MatrixXd slopes;  // n x 2: S_x, S_y
  Eigen::MatrixXd normal;  // A^T A and its Cholesky factor
  CglsWork work;
};

FitScratch& ThreadScratch() {
  thread_local FitScratch scratch;
  return scratch;
}

// Index of the term u^p v^q in the term order of the header.
int TermIndex(int p, int q) { return (p + q) * (p + q + 1) / 2 + q; }

TermMap GradientTerms(const TaylorPolynomial& poly) {
  TermMap terms(static_cast<size_t>(poly.terms() - 1));
  const double inv = 1.0 / poly.norm_radius_mm();
  for (int k = 1; k < poly.terms(); ++k) {
    const auto [a, b] = poly.Exponents(k);
    auto& t = terms[static_cast<size_t>(k - 1)];
    if (a >= 1) t.dx = TermIndex(a - 1, b), t.scale_x = a * inv;
    if (b >= 1) t.dy = TermIndex(a, b - 1), t.scale_y = b * inv;
  }
  return terms;
}

// T(i, j) = u_i^p v_i^q for the terms j = (p, q) of degree <= D - 1, each column from one of the previous degree:
// one multiplication per entry, vectorised over the points.
void BuildGradientBasis(const TaylorPolynomial& poly, const std::vector<Eigen::Vector2d>& points_mm,
                        Eigen::MatrixXd* T) {
  const Eigen::Index n = static_cast<Eigen::Index>(points_mm.size());
  const int top = poly.degree() - 1;
  T->resize(n, TaylorPolynomial::TermCount(top));
  if (top < 0) return;
  const double inv = 1.0 / poly.norm_radius_mm();
  T->col(0).setOnes();
  if (top == 0) return;
  // Degree 1 holds u and v themselves.
  for (Eigen::Index i = 0; i < n; ++i) {
    (*T)(i, 1) = points_mm[static_cast<size_t>(i)].x() * inv;
    (*T)(i, 2) = points_mm[static_cast<size_t>(i)].y() * inv;
  }
  for (int d = 2; d <= top; ++d) {
    for (int q = 0; q < d; ++q) T->col(TermIndex(d - q, q)) = T->col(TermIndex(d - q - 1, q)).cwiseProduct(T->col(1));
    T->col(TermIndex(0, d)) = T->col(TermIndex(0, d - 1)).cwiseProduct(T->col(2));
  }
}

struct GradientOperator {
  const Eigen::MatrixXd& T;
  const TermMap& terms;
  // A x as an n x 2 matrix (d Psi / dx, d Psi / dy at the points).
  void Apply(const Eigen::VectorXd& x, Eigen::MatrixXd* g, Eigen::MatrixXd* out) const {
    g->setZero(T.cols(), 2);
    for (size_t k = 0; k < terms.size(); ++k) {
      const TermMap::value_type& t = terms[k];
      const double c = x[static_cast<Eigen::Index>(k)];
      if (t.dx >= 0) (*g)(t.dx, 0) = t.scale_x * c;
      if (t.dy >= 0) (*g)(t.dy, 1) = t.scale_y * c;
    }
    // Eigen's general product packs T into a fresh buffer on every call. Instead, blocks of 8 rows keep both sums
    // in registers over all the columns: T is read once and `out` written once (the column-by-column axpy this
    // replaces read and wrote `out` once per column: ~8 % of a harness case). Each entry is the same sum in the
    // same order, 0 + g_0 T_i0 + g_1 T_i1 + ..., so the result is the axpy's bit for bit.
    const Eigen::Index n = T.rows(), m = T.cols();
    out->resize(n, 2);
    const double* gx = g->col(0).data();
    const double* gy = g->col(1).data();
    const auto rows = [&](auto block, Eigen::Index i) {
      using Block = Eigen::Array<double, decltype(block)::value, 1>;
      Block sx = Block::Zero(), sy = Block::Zero();
      for (Eigen::Index j = 0; j < m; ++j) {
        const Eigen::Map<const Block> t(T.col(j).data() + i);
        sx += gx[j] * t;
        sy += gy[j] * t;
      }
      Eigen::Map<Block>(out->col(0).data() + i) = sx;
      Eigen::Map<Block>(out->col(1).data() + i) = sy;
    };
    Eigen::Index i = 0;
    for (; i + 8 <= n; i += 8) rows(std::integral_constant<int, 8>(), i);
    for (; i < n; ++i) rows(std::integral_constant<int, 1>(), i);
  }
  // A^T r for r given as an n x 2 matrix.
  void ApplyTransposed(const Eigen::MatrixXd& r, Eigen::MatrixXd* h, Eigen::VectorXd* out) const {
    h->resize(T.cols(), 2);
    for (Eigen::Index j = 0; j < T.cols(); ++j) {
      (*h)(j, 0) = T.col(j).dot(r.col(0));
      (*h)(j, 1) = T.col(j).dot(r.col(1));
    }
    out->resize(static_cast<Eigen::Index>(terms.size()));
    for (size_t k = 0; k < terms.size(); ++k) {
      const TermMap::value_type& t = terms[k];
      double sum = 0;
      if (t.dx >= 0) sum += t.scale_x * (*h)(t.dx, 0);
      if (t.dy >= 0) sum += t.scale_y * (*h)(t.dy, 1);
      (*out)[static_cast<Eigen::Index>(k)] = sum;
    }
  }
};

// Preconditioned CGLS on min |A x - b| with x = R^-1 y, warm-started at x. True when the preconditioned normal
// residual |R^-T A^T (b - A x)| falls below `tolerance` times its value at x = 0.
bool PreconditionedCgls(const GradientOperator& A, const Eigen::MatrixXd& b, const Eigen::MatrixXd& R,
                        Eigen::VectorXd* x, CglsWork* w) {
  // 1e-14: the normal residual of a QR solution in double on this problem is ~1e-15 relative; CGLS stops close
  // above. (1e-13 left a cold first fit from the Cholesky factor 4e-11 from the QR solution; 1e-14 took as many
  // iterations over the paper sweep and 40 harness cases, 2-16, median 7, never the budget.)
  constexpr double kTolerance = 1e-14;
  constexpr int kMaxIterations = 25;
  const auto Rt = R.triangularView<Eigen::Upper>();
  A.Apply(*x, &w->g, &w->q);
  w->r = b - w->q;
  A.ApplyTransposed(w->r, &w->h, &w->s);
  Rt.transpose().solveInPlace(w->s);
  // The normal residual at x = 0, R^-T A^T b = R^-T A^T r + R x (A^T A = R^T R), without a product with A.
  const double reference = (w->s + Rt * (*x)).norm();
  w->p = w->s;
  double gamma = w->s.squaredNorm();
  for (int it = 0; it < kMaxIterations; ++it) {
    if (std::sqrt(gamma) <= kTolerance * reference) return true;
    w->rp = w->p;
    Rt.solveInPlace(w->rp);
    A.Apply(w->rp, &w->g, &w->q);
    const double qq = w->q.squaredNorm();
    if (!(qq > 0)) return false;
    const double alpha = gamma / qq;
    *x += alpha * w->rp;
    w->r -= alpha * w->q;
    A.ApplyTransposed(w->r, &w->h, &w->s);
    Rt.transpose().solveInPlace(w->s);
    const double gamma_next = w->s.squaredNorm();
    w->p = w->s + (gamma_next / gamma) * w->p;
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
// y rows of the gradient). The moments up to degree 2D - 2 are ~190 dot products of two columns of the gradient
// basis T (monomials of degree <= D - 1), against the 2 m n^2 of forming A^T A from A. Lower triangle only.
void NormalMatrixFromMoments(const TaylorPolynomial& poly, const Eigen::MatrixXd& T, const TermMap& terms,
                             Eigen::MatrixXd* normal) {
  constexpr int kMaxMoment = 2 * kMaxDegree - 2;
  const int top = poly.degree() - 1;
  double moments[kMaxMoment + 1][kMaxMoment + 1] = {};
  for (int p = 0; p <= 2 * top; ++p) {
    for (int q = 0; p + q <= 2 * top; ++q) {
      if (p + q <= top) {
        moments[p][q] = T.col(TermIndex(p, q)).sum();
        continue;
      }
      // u^p v^q = (u^p1 v^q1) (u^p2 v^q2), both of degree <= D - 1.
      const int p1 = std::min(p, top), q1 = top - p1;
      moments[p][q] = T.col(TermIndex(p1, q1)).dot(T.col(TermIndex(p - p1, q - q1)));
    }
  }
  const int unknowns = poly.terms() - 1;
  normal->resize(unknowns, unknowns);
  for (int k = 1; k <= unknowns; ++k) {
    const auto [a, b] = poly.Exponents(k);
    const auto& tk = terms[static_cast<size_t>(k - 1)];
    for (int l = 1; l <= k; ++l) {
      const auto [c, d] = poly.Exponents(l);
      const auto& tl = terms[static_cast<size_t>(l - 1)];
      double sum = 0;
      if (a >= 1 && c >= 1) sum += tk.scale_x * tl.scale_x * moments[a + c - 2][b + d];
      if (b >= 1 && d >= 1) sum += tk.scale_y * tl.scale_y * moments[a + c][b + d - 2];
      (*normal)(k - 1, l - 1) = sum;
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
bool FactorNormalEquations(const TaylorPolynomial& poly, const Eigen::MatrixXd& T, const TermMap& terms,
                           Eigen::MatrixXd* normal, Eigen::MatrixXd* r) {
  NormalMatrixFromMoments(poly, T, terms, normal);
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(*normal);  // in place: L in the lower triangle
  if (llt.info() != Eigen::Success) return false;
  const auto diag = normal->diagonal().cwiseAbs();
  if (!(diag.minCoeff() > 1e-6 * diag.maxCoeff())) return false;
  *r = normal->transpose().triangularView<Eigen::Upper>();
  return r->allFinite();
}

void SetCoefficients(const Eigen::VectorXd& b, double z_at_origin_mm, TaylorPolynomial* poly) {
  const int unknowns = static_cast<int>(b.size());
  poly->coefficients().tail(unknowns) = b;
  // Psi(0, 0) is the piston alone (every other monomial vanishes at the origin).
  poly->coefficients()(0) = z_at_origin_mm;
}

GradientFit Finish(const Eigen::MatrixXd& A, const Eigen::VectorXd& rhs, const Eigen::VectorXd& b,
                   double z_at_origin_mm, TaylorPolynomial* poly) {
  GradientFit fit;
  SetCoefficients(b, z_at_origin_mm, poly);
  fit.rms_slope_residual = std::sqrt((A * b - rhs).squaredNorm() / A.rows());
  fit.ok = true;
  return fit;
}

// After PreconditionedCgls: its residual b - A x (updated by recurrence, equal to the explicit one to rounding)
// gives the rms.
GradientFit Finish(const CglsWork& w, const Eigen::VectorXd& b, double z_at_origin_mm, TaylorPolynomial* poly) {
  GradientFit fit;
  SetCoefficients(b, z_at_origin_mm, poly);
  fit.rms_slope_residual = std::sqrt(w.r.squaredNorm() / static_cast<double>(w.r.size()));
  fit.ok = true;
  return fit;
}

}  // namespace

GradientFit GradientFitter::Fit(const std::vector<Eigen::Vector2d>& points_mm,
                                const std::vector<Eigen::Vector2d>& slopes, double z_at_origin_mm,
                                TaylorPolynomial* poly) {
  const int unknowns = poly->terms() - 1;
  const int n = static_cast<int>(points_mm.size());
  if (2 * n < unknowns || slopes.size() != points_mm.size()) return {};
  if (terms_degree_ != poly->degree() || terms_radius_mm_ != poly->norm_radius_mm()) {
    terms_ = GradientTerms(*poly);
    terms_degree_ = poly->degree();
    terms_radius_mm_ = poly->norm_radius_mm();
  }
  FitScratch& w = ThreadScratch();
  BuildGradientBasis(*poly, points_mm, &w.basis);
  w.slopes.resize(n, 2);
  for (int i = 0; i < n; ++i) w.slopes.row(i) = slopes[static_cast<size_t>(i)].transpose();
  const GradientOperator A{w.basis, terms_};
  Eigen::VectorXd x = poly->coefficients().tail(unknowns);
  if (started_ && r_.rows() == unknowns && PreconditionedCgls(A, w.slopes, r_, &x, &w.work)) {
    return Finish(w.work, x, z_at_origin_mm, poly);
  }
  started_ = false;
  ++factorizations_;
  // The factor of these points: from the normal equations (cheap), by QR when they are too ill-conditioned to
  // serve or CGLS does not converge with their factor.
  x = poly->coefficients().tail(unknowns);
  if (FactorNormalEquations(*poly, w.basis, terms_, &w.normal, &r_) &&
      PreconditionedCgls(A, w.slopes, r_, &x, &w.work)) {
    return Finish(w.work, x, z_at_origin_mm, poly);
  }
  Eigen::MatrixXd design;
  Eigen::VectorXd rhs;
  BuildDesign(*poly, points_mm, slopes, &design, &rhs);
  x = poly->coefficients().tail(unknowns);
  if (!SolveByQr(design, rhs, &x, &r_)) {
    r_.resize(0, 0);
    return {};
  }
  return Finish(design, rhs, x, z_at_origin_mm, poly);
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
