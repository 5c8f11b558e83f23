#pragma once
// The modal surface of paper Eq. 21: Psi(x, y) = sum_k B_k psi_k(x, y), Taylor monomials of total degree <= D
// (D = 9 gives the paper's N = 55 terms), evaluated in normalised coordinates u = x / R, v = y / R so that the
// least-squares problems stay well conditioned (R = the radius of the data).
//
// Term order: by total degree d = 0..D, and within a degree by falling power of u:
//   psi_1 = 1, psi_2 = u, psi_3 = v, psi_4 = u^2, psi_5 = u v, psi_6 = v^2, psi_7 = u^3, ...
// so B_1 is the piston and B_2, B_3 the tilts (paper Sec. 4.2 zeroes them for the power maps).
#include <vector>

#include <Eigen/Core>

namespace topocal::topo {

class TaylorPolynomial {
 public:
  TaylorPolynomial() = default;
  TaylorPolynomial(int degree, double norm_radius_mm);

  static int TermCount(int degree) { return (degree + 1) * (degree + 2) / 2; }
  int degree() const { return degree_; }
  int terms() const { return static_cast<int>(coefficients_.size()); }
  double norm_radius_mm() const { return norm_radius_mm_; }
  const Eigen::VectorXd& coefficients() const { return coefficients_; }
  Eigen::VectorXd& coefficients() { return coefficients_; }
  // Exponents (a, b) of term k (0-based): psi_k = u^a v^b.
  std::pair<int, int> Exponents(int k) const { return exponents_[k]; }

  double Value(double x_mm, double y_mm) const;
  // Value and gradient (mm, dimensionless slopes).
  void ValueAndGradient(double x_mm, double y_mm, double* z, double* zx, double* zy) const;
  // ValueAndGradient at `count` points (x_mm[i], y_mm[i]), each bit for bit the single-point result (the same
  // operations in the same order), four points interleaved so that their Horner chains overlap.
  void ValueAndGradientMany(int count, const double* x_mm, const double* y_mm, double* z, double* zx,
                            double* zy) const;
  // Value, gradient and Hessian (1/mm).
  void Derivatives(double x_mm, double y_mm, double* z, double* zx, double* zy, double* zxx, double* zxy,
                   double* zyy) const;

  // Psi along the meridian at angle theta as a polynomial in rho: Psi(rho cos t, rho sin t) = sum_d g[d] rho^d,
  // d = 0..degree (g has degree + 1 entries, in mm^(1-d)).
  void MeridianCoefficients(double theta_rad, double* g) const;

  // Rows of d psi_k / dx and d psi_k / dy at a point, for the gradient fit (k = 1..N-1: the piston has no gradient).
  void GradientRows(double x_mm, double y_mm, double* row_x, double* row_y) const;

 private:
  int degree_ = 0;
  double norm_radius_mm_ = 1.0;
  Eigen::VectorXd coefficients_;
  std::vector<std::pair<int, int>> exponents_;
};

struct GradientFit {
  bool ok = false;
  double rms_slope_residual = 0;  // rms of the fitted minus measured slopes (dimensionless)
};

namespace internal {
// Term k + 1 of Psi (unknown k of the gradient fit) in the gradient's monomial table (GradientFitter): d/dx of
// u^a v^b is (a / R) u^(a-1) v^b, column dx of the table; d/dy is (b / R) u^a v^(b-1), column dy (-1: no such
// component).
struct GradientTerm {
  int dx = -1, dy = -1;
  double scale_x = 0, scale_y = 0;
};
}  // namespace internal

// Repeated gradient fits on slowly moving points (the normal-refinement loop). Each fit factors the normal matrix
// A^T A of its own points by Cholesky, from the points' moments (R = L^T; Householder QR of A when the normal
// matrix is too ill-conditioned), and solves the least-squares problem by CGLS preconditioned with R,
// warm-started from the previous coefficients: A R^-1 is orthonormal to ~1e-8, so CGLS lands on the QR solution
// (to ~1e-13) in about 2 iterations. CGLS never forms A (1248 x 65 for the paper's 624 spots): its products are
// products with the table of the gradient's monomials at the points (taylor_polynomial.cc). Reusing the
// first fit's R for the later fits (as an earlier version did) took 7-8 iterations per fit, more than the new factor
// costs. A fitter started from another fit's R (StartFrom: Monte Carlo draws of slightly moved spots) keeps using
// that R while CGLS converges with it, and factors anew only when it does not. Written by hand because Eigen's
// iterative solvers take sparse or square systems, not a matrix-free rectangular one with a triangular
// preconditioner.
class GradientFitter {
 public:
  GradientFit Fit(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes,
                  double z_at_origin_mm, TaylorPolynomial* poly);
  int factorizations() const { return factorizations_; }
  // The R of the last factorisation (empty before the first), and a fitter that starts from another fit's R:
  // refits of slightly moved points (Monte Carlo draws of a calibration) then need no factorisation of their own.
  const Eigen::MatrixXd& factor() const { return r_; }
  void StartFrom(const Eigen::MatrixXd& r) {
    r_ = r;
    started_ = true;
  }

 private:
  Eigen::MatrixXd r_;        // upper-triangular factor (empty before the first fit)
  std::vector<internal::GradientTerm> terms_;
  int terms_degree_ = -1;
  double terms_radius_mm_ = 0;
  int factorizations_ = 0;
  bool started_ = false;  // r_ came from StartFrom and still serves
};

// Fits B_2..B_N to measured slopes (S_x, S_y) at points (x, y) (paper Eq. 21-22 modal reconstruction) by
// column-pivoting Householder QR, then sets the piston B_1 so that Psi(0, 0) = z_at_origin_mm.
// Needs at least N - 1 distinct slope equations; returns ok = false otherwise or on a rank-deficient system.
GradientFit FitGradient(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes,
                        double z_at_origin_mm, TaylorPolynomial* poly);

}  // namespace topocal::topo
