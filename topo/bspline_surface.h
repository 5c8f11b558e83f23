#pragma once
// A local surface representation for freeform corneas (docs/reconstruction.md gives the
// measurements that chose it): uniform bicubic B-splines on the square [-L, L]^2,
//   B(x, y) = sum_{i,j} c_ij N_i(x) N_j(y),   knots every h mm,
// fitted to slope residuals with a difference penalty on the coefficients (a "P-spline", Eilers & Marx 1996):
//   min  sum_k |grad B(p_k) - s_k|^2 + lambda |D c|^2,   D = differences of order `penalty_order` along x and y,
// lambda chosen by restricted maximum likelihood (REML, the smoothing parameter as a variance ratio: Wood 2011),
// which needs only log det M from the factorisation (GCV needed tr H, estimated with seeded probes: noisy, and
// misled on ablations; docs/reconstruction.md). Each slope touches 16 coefficients, so in grid order the normal
// matrix is a band (~1,000 unknowns for 4.6 mm, h = 0.33), solved by LAPACK's band Cholesky (topo/band_cholesky.h).
//
// The piston is not observed by slopes nor by the penalty: B(0, 0) is set to 0 (the B-splines sum to one, so a
// constant shift of all coefficients moves the piston alone). Outside the data the penalty alone shapes B: do not
// use it beyond the covered radius (the analysis flags maps there).
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "topo/band_cholesky.h"

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
  double lambda_min = 1e-8;   // REML over the grid lambda / lambda_scale = lambda_max / lambda_step^k in
  double lambda_max = 1e2;    // [lambda_min, lambda_max], lambda_scale = tr(A^T A) / tr(D^T D); walked from the
  double lambda_step = 100;   // grid point nearest lambda_start towards the smaller criterion until it rises
  double lambda_start = 1e-4; // (3 factorisations when REML's minimum is there, instead of one per grid point)
  int support_margin = 1;     // rings of coefficients solved for around those whose support holds a point
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

// The same fit, repeated as the reconstruction refines its points (micrometres between passes). The unknowns are
// the coefficients near the data (SplineFitOptions::support_margin) and those of holes the data enclose; the others,
// outside the data, are 0. M = A^T A + lambda P is assembled in place on a pattern built once for them (every pair
// of unknowns within 3 grid steps), and every fit factorises its own M (a band: topo/band_cholesky.h): a refit equals
// a fresh fit exactly. lambda by REML walks the grid from lambda_start (3 factorisations when REML's minimum is
// there) and keeps the chosen one's factorisation for the trace probes. Measured 2026-12-02 (docs/reconstruction.md,
// "The spline's cost").
class SplineSlopeFitter {
 public:
  SplineFit Fit(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes, double lambda,
                const SplineFitOptions& options, BSplineSurface* spline);

 private:
  using SparseMatrix = Eigen::SparseMatrix<double>;
  // Natural ordering: the coefficients in grid order (row by row) make M a band of half-width band_ (3 grid rows
  // and 3 coefficients), factorised as such by LAPACK (topo/band_cholesky.h).
  // Two factorisations: the REML walk factorises each lambda into the slot that does not hold the best so far, so
  // the chosen lambda's factorisation is kept (for the trace probes) without a repeat.
  BandCholesky solvers_[2];
  int band_ = 0;               // M's half-bandwidth in the unknowns' order
  int best_ = 0;               // the slot that holds the chosen lambda's factorisation
  std::vector<int> pattern_key_;  // the unknowns (and the penalty order) of the analysed pattern
  SparseMatrix m_;                // M's pattern (both triangles) and the values of the last M assembled
  std::vector<double> ata_values_, penalty_values_;  // A^T A and the penalty D^T D on m_'s pattern
  std::vector<int> diagonal_;     // places of the diagonal in m_'s values
  std::vector<int> local_;        // per unknown (column), the place of each neighbour (span_ x span_) in m_'s values
  std::vector<int> grid_of_;      // the grid index of each unknown
  int span_ = 0, half_span_ = 0;
  // The place in m_'s values of (row, column) unknowns (both in the neighbourhood).
  int Place(int row, int column, int side) const {
    const int dr = grid_of_[row] / side - grid_of_[column] / side, dc = grid_of_[row] % side - grid_of_[column] % side;
    return local_[(static_cast<size_t>(column) * span_ + dr + half_span_) * span_ + dc + half_span_];
  }
  int analyses_ = 0;
  int factorisations_ = 0;

  // Fit's steps.
  struct Observations;  // the points' gradient stencils, their slopes and the unknowns (topo/bspline_surface.cc)
  // The pattern of M for these unknowns (index: the unknown of each grid coefficient, -1 for none), the penalty on
  // it and the places of its diagonal.
  void BuildPattern(const std::vector<int>& index, int side, int unknowns, int penalty_order);
  // A^T A into ata_values_; returns A^T b.
  Eigen::VectorXd AssembleNormalEquations(const Observations& obs);
  // Assembles M(lam) = A^T A + lam P + ridge I, factorises it into solvers_[slot] and solves for c.
  bool SolveAt(int slot, double lam, double ridge, const Eigen::VectorXd& Atb, Eigen::VectorXd* c);
  // lambda by REML (the walk over the grid lambda / scale): sets fit->lambda, *c and best_; false if none holds.
  bool ChooseLambdaByReml(const Observations& obs, const Eigen::VectorXd& Atb, double scale, double ridge,
                          const SplineFitOptions& options, SplineFit* fit, Eigen::VectorXd* c);

 public:
  int analyses() const { return analyses_; }              // patterns built so far (diagnostics, tests)
  int factorisations() const { return factorisations_; }  // numeric factorisations so far (diagnostics, tests)
};

}  // namespace topocal::topo
