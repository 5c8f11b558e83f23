#include "topo/bspline_surface.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/SparseCholesky>

namespace topocal::topo {

BSplineSurface::BSplineSurface(double half_width_mm, double spacing_mm) {
  intervals_ = std::max(1, static_cast<int>(std::ceil(2.0 * half_width_mm / spacing_mm)));
  n_ = intervals_ + 3;
  half_width_ = half_width_mm;
  h_ = 2.0 * half_width_mm / intervals_;
  c_ = Eigen::VectorXd::Zero(n_ * n_);
}

void BSplineSurface::Basis(double t_mm, int* first, double* b, double* db, double* d2b) const {
  const double s = (t_mm + half_width_) / h_;
  // Beyond [-L, L] the end intervals' polynomials continue (extrapolation; the analysis never samples there).
  const int m = std::clamp(static_cast<int>(std::floor(s)), 0, intervals_ - 1);
  const double u = s - m, v = 1.0 - u;
  *first = m;
  b[0] = v * v * v / 6.0;
  b[1] = (3.0 * u * u * u - 6.0 * u * u + 4.0) / 6.0;
  b[2] = (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) / 6.0;
  b[3] = u * u * u / 6.0;
  const double ih = 1.0 / h_;
  db[0] = -0.5 * v * v * ih;
  db[1] = (1.5 * u * u - 2.0 * u) * ih;
  db[2] = (-1.5 * u * u + u + 0.5) * ih;
  db[3] = 0.5 * u * u * ih;
  d2b[0] = v * ih * ih;
  d2b[1] = (3.0 * u - 2.0) * ih * ih;
  d2b[2] = (1.0 - 3.0 * u) * ih * ih;
  d2b[3] = u * ih * ih;
}

BSplineSurface::TensorBasis BSplineSurface::BasisAt(double x, double y) const {
  TensorBasis t;
  Basis(x, &t.mx, t.bx, t.dbx, t.d2bx);
  Basis(y, &t.my, t.by, t.dby, t.d2by);
  return t;
}

double BSplineSurface::Value(double x, double y) const {
  double z, zx, zy, zxx, zxy, zyy;
  Derivatives(x, y, &z, &zx, &zy, &zxx, &zxy, &zyy);
  return z;
}

void BSplineSurface::Derivatives(double x, double y, double* z, double* zx, double* zy, double* zxx, double* zxy,
                                 double* zyy) const {
  const auto [mx, my, bx, dbx, d2bx, by, dby, d2by] = BasisAt(x, y);
  *z = *zx = *zy = *zxx = *zxy = *zyy = 0;
  for (int j = 0; j < 4; ++j) {
    for (int i = 0; i < 4; ++i) {
      const double c = c_[(my + j) * n_ + (mx + i)];
      *z += c * bx[i] * by[j];
      *zx += c * dbx[i] * by[j];
      *zy += c * bx[i] * dby[j];
      *zxx += c * d2bx[i] * by[j];
      *zxy += c * dbx[i] * dby[j];
      *zyy += c * bx[i] * d2by[j];
    }
  }
}

void BSplineSurface::GradientStencil(double x, double y, int* index, double* wx, double* wy) const {
  const auto [mx, my, bx, dbx, d2bx, by, dby, d2by] = BasisAt(x, y);
  for (int j = 0; j < 4; ++j) {
    for (int i = 0; i < 4; ++i) {
      index[4 * j + i] = (my + j) * n_ + (mx + i);
      wx[4 * j + i] = dbx[i] * by[j];
      wy[4 * j + i] = bx[i] * dby[j];
    }
  }
}

namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;

// D^T D for differences of `order` along both axes of an n x n coefficient grid.
SparseMatrix DifferencePenalty(int n, int order) {
  // 1-D difference matrix of the given order: (n - order) x n.
  Eigen::MatrixXd d1 = Eigen::MatrixXd::Identity(n, n);
  for (int k = 0; k < order; ++k) {
    Eigen::MatrixXd next(d1.rows() - 1, n);
    for (int r = 0; r + 1 < d1.rows(); ++r) next.row(r) = d1.row(r + 1) - d1.row(r);
    d1 = next;
  }
  const Eigen::MatrixXd dtd = d1.transpose() * d1;  // n x n, banded
  std::vector<Eigen::Triplet<double>> t;
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      if (dtd(a, b) == 0) continue;
      for (int k = 0; k < n; ++k) {
        t.emplace_back(k * n + a, k * n + b, dtd(a, b));  // along x (index = row * n + column)
        t.emplace_back(a * n + k, b * n + k, dtd(a, b));  // along y
      }
    }
  }
  SparseMatrix p(n * n, n * n);
  p.setFromTriplets(t.begin(), t.end());
  return p;
}

}  // namespace

SplineFit FitSplineToSlopes(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes,
                            double lambda, const SplineFitOptions& o, BSplineSurface* spline) {
  return SplineSlopeFitter().Fit(points_mm, slopes, lambda, o, spline);
}

SplineFit SplineSlopeFitter::Fit(const std::vector<Eigen::Vector2d>& points_mm,
                                 const std::vector<Eigen::Vector2d>& slopes, double lambda, const SplineFitOptions& o,
                                 BSplineSurface* spline) {
  SplineFit fit;
  const int n = static_cast<int>(points_mm.size());
  const int p = spline->unknowns();
  if (n == 0 || slopes.size() != points_mm.size() || p == 0) return fit;
  if (p != unknowns_) {  // another spline: nothing of the previous one applies
    factorised_ = false;
    unknowns_ = p;
  }
  // The sparsity pattern of A^T A depends on which knot cells hold points: a refactorisation orders afresh.
  bool analysed = false;
  const int side = static_cast<int>(std::lround(std::sqrt(p)));
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(32 * n);
  Eigen::VectorXd rhs(2 * n);
  int idx[16];
  double wx[16], wy[16];
  for (int k = 0; k < n; ++k) {
    spline->GradientStencil(points_mm[k].x(), points_mm[k].y(), idx, wx, wy);
    for (int q = 0; q < 16; ++q) {
      t.emplace_back(2 * k, idx[q], wx[q]);
      t.emplace_back(2 * k + 1, idx[q], wy[q]);
    }
    rhs(2 * k) = slopes[k].x();
    rhs(2 * k + 1) = slopes[k].y();
  }
  SparseMatrix A(2 * n, p);
  A.setFromTriplets(t.begin(), t.end());
  const SparseMatrix AtA = SparseMatrix(A.transpose() * A);
  const Eigen::VectorXd Atb = A.transpose() * rhs;
  const SparseMatrix P = DifferencePenalty(side, o.penalty_order);
  // The constant (and, for order >= 2, more) is in the null space of both the slopes and the penalty: a ridge far
  // below either term fixes it (the piston is then set explicitly).
  SparseMatrix ridge(p, p);
  ridge.setIdentity();
  const double scale = AtA.diagonal().sum() / std::max(1e-300, P.diagonal().sum());
  ridge *= 1e-12 * AtA.diagonal().sum() / p;

  const auto factorise = [&](const SparseMatrix& M, double lam) {
    // The pattern does not depend on lambda: analyse once per call, factorise per lambda.
    if (!analysed) {
      solver_.analyzePattern(M);
      analysed = true;
    }
    solver_.factorize(M);
    factorised_ = solver_.info() == Eigen::Success;
    factorised_lambda_ = lam;
    return factorised_;
  };
  const auto solve = [&](double lam, Eigen::VectorXd* c) {
    const SparseMatrix M = AtA + lam * P + ridge;
    if (!factorise(M, lam)) return false;
    *c = solver_.solve(Atb);
    return solver_.info() == Eigen::Success && c->allFinite();
  };
  // Conjugate gradients on M c = Atb preconditioned by the factorisation of a nearby M. Hand-written (a dozen
  // lines) because Eigen's ConjugateGradient takes its preconditioner by type and would copy the factorisation.
  const auto solve_by_cg = [&](double lam, Eigen::VectorXd* c) {
    constexpr int kMaxSteps = 12;
    constexpr double kRelativeResidual = 1e-13;
    const SparseMatrix M = AtA + lam * P + ridge;
    Eigen::VectorXd x = solver_.solve(Atb);
    Eigen::VectorXd r = Atb - M * x;
    const double target = kRelativeResidual * Atb.norm();
    Eigen::VectorXd z = solver_.solve(r);
    Eigen::VectorXd d = z;
    double rz = r.dot(z);
    for (int step = 0; step < kMaxSteps; ++step) {
      if (r.norm() <= target) {
        *c = std::move(x);
        return c->allFinite();
      }
      const Eigen::VectorXd Md = M * d;
      const double alpha = rz / d.dot(Md);
      x += alpha * d;
      r -= alpha * Md;
      z = solver_.solve(r);
      const double rz_next = r.dot(z);
      d = z + (rz_next / rz) * d;
      rz = rz_next;
    }
    if (r.norm() <= target) {
      *c = std::move(x);
      return c->allFinite();
    }
    return false;
  };
  Eigen::VectorXd c;
  if (lambda < 0) {
    // lambda by restricted maximum likelihood (REML) over a log grid. With c ~ N(0, sigma^2 / lambda P^-) and
    // sigma^2 profiled out, -2 log L_R = (m - nu) log(RSS + lambda c'Pc) + log det M - (p - nu) log lambda + const
    // (nu = order^2: the penalty's null space, polynomials of degree < order in x and in y). log det M is the sum
    // of log D of the LDL^T factor: one factorisation per lambda and no trace. It replaced GCV with a Hutchinson
    // trace (docs/reconstruction.md, "The spline's cost"): GCV, even with the exact trace, has its global minimum
    // at the interpolating end of the grid on the hyperopic +6 D ablation (axial max 2.5 D) and was kept off it
    // only by the estimator's noise; REML chose a lambda that holds the whole test set, exact and noisy.
    const double m = 2.0 * n;
    const int null_dim = o.penalty_order * o.penalty_order;
    std::mt19937 rng(o.seed);
    std::bernoulli_distribution coin(0.5);
    std::vector<Eigen::VectorXd> probes(o.trace_probes, Eigen::VectorXd(p));
    for (auto& z : probes)
      for (int i = 0; i < p; ++i) z(i) = coin(rng) ? 1.0 : -1.0;
    double best_reml = INFINITY;
    // From the smoothest end: the criterion falls to its minimum and rises, so the trace (below) is estimated at
    // the few lambdas that improve on the best so far.
    for (double rel = o.lambda_max; rel >= o.lambda_min * 0.9999; rel /= o.lambda_step) {
      const double lam = rel * scale;
      Eigen::VectorXd ci;
      if (!solve(lam, &ci)) continue;
      const double fit_and_penalty = (A * ci - rhs).squaredNorm() + lam * ci.dot(P * ci);
      const double log_det = solver_.vectorD().array().log().sum();
      if (!(fit_and_penalty > 0) || !std::isfinite(log_det)) continue;
      const double reml = (m - null_dim) * std::log(fit_and_penalty) + log_det - (p - null_dim) * std::log(lam);
      if (reml < best_reml) {
        best_reml = reml;
        fit.lambda = lam;
        c = ci;
        // The effective number of parameters tr H = tr(M^-1 A^T A) (the adequacy figure's degrees of freedom):
        // Hutchinson's estimator with seeded Rademacher probes.
        double trace = 0;
        for (const auto& z : probes) trace += z.dot(solver_.solve(AtA * z));
        fit.effective_params = trace / o.trace_probes;
      }
    }
    if (!std::isfinite(best_reml)) return fit;
    // The factorisation left behind is the grid's last lambda: refactorise at the chosen one for the refits.
    factorised_ = false;
  } else {
    fit.lambda = lambda;
    const bool reused = factorised_ && factorised_lambda_ == lambda && solve_by_cg(lambda, &c);
    if (reused) {
      ++refits_by_cg_;
    } else if (!solve(lambda, &c)) {
      return fit;
    }
  }
  spline->coefficients() = c;
  // Piston: B(0, 0) = 0 (the basis is a partition of unity).
  spline->coefficients().array() -= spline->Value(0.0, 0.0);
  fit.rms_slope_residual = std::sqrt((A * c - rhs).squaredNorm() / (2.0 * n));
  fit.ok = true;
  return fit;
}

}  // namespace topocal::topo
