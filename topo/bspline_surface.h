#pragma once
// A local surface representation for freeform corneas (issue 18, item 2; docs/reconstruction.md gives the
// measurements that chose it): uniform bicubic B-splines on the square [-L, L]^2,
//   B(x, y) = sum_{i,j} c_ij N_i(x) N_j(y),   knots every h mm,
// fitted to slope residuals with a difference penalty on the coefficients (a "P-spline", Eilers & Marx 1996):
//   min  sum_k |grad B(p_k) - s_k|^2 + lambda |D c|^2,   D = differences of order `penalty_order` along x and y,
// lambda chosen by restricted maximum likelihood (REML, the smoothing parameter as a variance ratio: Wood 2011),
// which needs only log det M from the factorisation (GCV needed tr H, estimated with seeded probes: noisy, and
// misled on ablations; docs/reconstruction.md). Solved with Eigen's sparse
// Cholesky: each slope touches 16 coefficients, so the normal matrix is banded (~900 unknowns for 4.6 mm, h = 0.33).
//
// The piston is not observed by slopes nor by the penalty: B(0, 0) is set to 0 (the B-splines sum to one, so a
// constant shift of all coefficients moves the piston alone). Outside the data the penalty alone shapes B: do not
// use it beyond the covered radius (the analysis flags maps there).
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

namespace topocal::topo {

class BSplineSurface {
 public:
  BSplineSurface() = default;
  // Knots every about `spacing_mm` (rounded so that an integer number of intervals spans [-L, L]).
  BSplineSurface(double half_width_mm, double spacing_mm);

  bool empty() const { return n_ == 0; }
  int unknowns() const { return n_ * n_; }
  double half_width_mm() const { return half_width_; }
  double spacing_mm() const { return h_; }
  const Eigen::VectorXd& coefficients() const { return c_; }
  Eigen::VectorXd& coefficients() { return c_; }

  double Value(double x_mm, double y_mm) const;
  void Derivatives(double x_mm, double y_mm, double* z, double* zx, double* zy, double* zxx, double* zxy,
                   double* zyy) const;
  // The 16 coefficients that act at (x, y) and the weights of d/dx and d/dy on them.
  void GradientStencil(double x_mm, double y_mm, int* index, double* wx, double* wy) const;

 private:
  // Interval and the 4 basis values and derivatives along one axis.
  void Basis(double t_mm, int* first, double* b, double* db, double* d2b) const;
  // Both axes' bases at (x, y): the first coefficient index and the 4 values and derivatives along each.
  struct TensorBasis {
    int mx, my;
    double bx[4], dbx[4], d2bx[4], by[4], dby[4], d2by[4];
  };
  TensorBasis BasisAt(double x_mm, double y_mm) const;
  int intervals_ = 0, n_ = 0;  // n_ = intervals_ + 3 coefficients per axis
  double half_width_ = 0, h_ = 1;
  Eigen::VectorXd c_;
};

struct SplineFitOptions {
  int penalty_order = 3;      // differences of the coefficients: 3 leaves curvature unpenalised (cones keep
                              // their peak power), penalising its change
  int trace_probes = 8;         // Rademacher vectors for tr H (effective parameters, at the chosen lambda)
  unsigned seed = 1;          // of the probes (determinism)
  double lambda_min = 1e-8;   // REML search over lambda / lambda_scale in [min, max], lambda_step apart,
  double lambda_max = 1e2;    // lambda_scale = tr(A^T A) / tr(D^T D) (6 factorisations: the search is the
  double lambda_step = 100;   // spline's main cost)
};

struct SplineFit {
  bool ok = false;
  double lambda = 0;             // the penalty weight used (absolute)
  double effective_params = 0;   // tr H at that lambda (when chosen by REML; Hutchinson estimate)
  double rms_slope_residual = 0;
};

// Fits `spline` (already sized) to the slopes; lambda < 0 chooses lambda by REML, otherwise uses it.
SplineFit FitSplineToSlopes(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes,
                            double lambda, const SplineFitOptions& options, BSplineSurface* spline);

// The same fit, repeated as the reconstruction refines its points: a refit with the previous lambda on the same
// spline reuses the previous factorisation of M = A^T A + lambda P as the preconditioner of conjugate gradients on
// the new system. Between iterations the points move by micrometres, M changes by far less than itself, and a few
// CG steps reach the direct solution (relative residual 1e-13); the sparse factorisation was ~40 % of a spline
// reconstruction (about one per iteration, 3 ms each for 961 unknowns). If CG does not converge in a few steps the
// system is factorised afresh, so the result never depends on the history beyond rounding.
class SplineSlopeFitter {
 public:
  SplineFit Fit(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes, double lambda,
                const SplineFitOptions& options, BSplineSurface* spline);

 private:
  using SparseMatrix = Eigen::SparseMatrix<double>;
  // Natural ordering: the coefficients in grid order (row by row) make M banded (half-bandwidth 3 rows + 3); its
  // symbolic analysis is ~0.5 ms against AMD's 1.4-8 ms on the keratoconus measurement, for a factorisation as fast
  // (nnz(L) 158 k against 130 k, 5.5-6 ms either way; measured 2026-12-02, docs/reconstruction.md).
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> solver_;
  bool factorised_ = false;    // solver_ holds a factorisation of M for factorised_lambda_
  double factorised_lambda_ = -1;
  int unknowns_ = 0;
  int refits_by_cg_ = 0;

 public:
  int refits_by_cg() const { return refits_by_cg_; }  // refits that reused a factorisation (diagnostics, tests)
};

}  // namespace topocal::topo
