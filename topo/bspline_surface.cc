#include "topo/bspline_surface.h"

#include <algorithm>
#include <cmath>
#include <random>

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

// D^T D for differences of `order` along both axes of an n x n coefficient grid, over the coefficients that
// index[] maps to an unknown (index[row * n + column] >= 0, the unknown's number; -1: not solved for): only the
// difference rows whose coefficients are all unknowns.
SparseMatrix DifferencePenalty(int n, int order, const std::vector<int>& index, int unknowns) {
  std::vector<double> w(order + 1);  // (-1)^(order - j) C(order, j)
  for (int j = 0; j <= order; ++j) {
    double binomial = 1;
    for (int q = 0; q < j; ++q) binomial = binomial * (order - q) / (q + 1);
    w[j] = ((order - j) % 2 ? -1.0 : 1.0) * binomial;
  }
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(2 * n * n * (order + 1));
  int rows = 0;
  for (int axis = 0; axis < 2; ++axis) {
    const int step = axis == 0 ? 1 : n;  // along x: the next column; along y: the next row
    for (int row = 0; row < n; ++row) {
      for (int col = 0; col + order < n; ++col) {
        const int first = axis == 0 ? row * n + col : col * n + row;
        bool inside = true;
        for (int j = 0; j <= order && inside; ++j) inside = index[first + j * step] >= 0;
        if (!inside) continue;
        for (int j = 0; j <= order; ++j) t.emplace_back(rows, index[first + j * step], w[j]);
        ++rows;
      }
    }
  }
  SparseMatrix d(rows, unknowns);
  d.setFromTriplets(t.begin(), t.end());
  return SparseMatrix(d.transpose() * d);
}

}  // namespace

// The points' gradient stencils (the 16 coefficients that act at each point and the weights of d/dx and d/dy on
// them), their slopes, and the unknown each grid coefficient maps to (-1: not solved for, set to 0).
struct SplineSlopeFitter::Observations {
  Observations(const std::vector<Eigen::Vector2d>& point_slopes, int points)
      : slopes(point_slopes), n(points), stencil(16 * static_cast<size_t>(n)),
        weight_x(16 * static_cast<size_t>(n)), weight_y(16 * static_cast<size_t>(n)) {}

  const std::vector<Eigen::Vector2d>& slopes;
  int n;
  std::vector<int> stencil;
  std::vector<double> weight_x, weight_y;
  std::vector<int> index;
  int unknowns = 0;

  // Slope residual of the coefficients c (on the unknowns): sum over the points of |grad B - s|^2.
  double ResidualSum(const Eigen::VectorXd& c) const {
    double sum = 0;
    for (int k = 0; k < n; ++k) {
      double gx = 0, gy = 0;
      for (int a = 0; a < 16; ++a) {
        const double ca = c(index[stencil[16 * k + a]]);
        gx += weight_x[16 * k + a] * ca;
        gy += weight_y[16 * k + a] * ca;
      }
      sum += (gx - slopes[k].x()) * (gx - slopes[k].x()) + (gy - slopes[k].y()) * (gy - slopes[k].y());
    }
    return sum;
  }
};

namespace {

// The unknowns: the coefficients whose support holds a point (touched), support_margin rings of coefficients
// around them, and every coefficient of a hole the data enclose (the screen's centre inside its first ring, spots a
// glint or a lash took): the penalty alone shapes those, and a hole set to 0 would put a pit of tens of diopters
// under fine knots (0.12 mm knots inside a first ring of radius 0.48 mm: 50 D in the central 0.5 mm). Only the
// coefficients the outside of the grid reaches without crossing the data are left out (set to 0). index[] gets each
// unknown's number in grid order (-1 for the others). Returns how many there are.
int NumberUnknowns(const std::vector<char>& touched, int side, int support_margin, std::vector<int>* index) {
  std::vector<char> near(touched.size(), 0);
  for (int row = 0; row < side; ++row) {
    for (int col = 0; col < side; ++col) {
      for (int dr = -support_margin; dr <= support_margin && !near[row * side + col]; ++dr) {
        for (int dc = -support_margin; dc <= support_margin; ++dc) {
          const int r2 = row + dr, c2 = col + dc;
          if (r2 >= 0 && r2 < side && c2 >= 0 && c2 < side && touched[r2 * side + c2]) {
            near[row * side + col] = 1;
            break;
          }
        }
      }
    }
  }
  // The outside: a flood over coefficients that are not near, from the grid's edge (4-connected).
  std::vector<char> outside(touched.size(), 0);
  std::vector<int> stack;
  const auto reach = [&](int row, int col) {
    const int at = row * side + col;
    if (row < 0 || row >= side || col < 0 || col >= side || near[at] || outside[at]) return;
    outside[at] = 1;
    stack.push_back(at);
  };
  for (int k = 0; k < side; ++k) reach(0, k), reach(side - 1, k), reach(k, 0), reach(k, side - 1);
  while (!stack.empty()) {
    const int at = stack.back();
    stack.pop_back();
    const int row = at / side, col = at % side;
    reach(row - 1, col), reach(row + 1, col), reach(row, col - 1), reach(row, col + 1);
  }
  int unknowns = 0;
  for (int at = 0; at < side * side; ++at) {
    if (!outside[at]) (*index)[at] = unknowns++;
  }
  return unknowns;
}

// The effective number of parameters tr H = tr(M^-1 A^T A) (the adequacy figure's degrees of freedom), with M
// factorised in `solver`: Hutchinson's estimator with seeded Rademacher probes.
double EffectiveParameters(const BandCholesky& solver, const Eigen::Map<const SparseMatrix>& AtA, int pr,
                           const SplineFitOptions& o) {
  std::mt19937 rng(o.seed);
  std::bernoulli_distribution coin(0.5);
  // The probes are solved together (one pass over the factor).
  Eigen::MatrixXd z(pr, o.trace_probes);
  for (int k = 0; k < o.trace_probes; ++k) {
    for (int i = 0; i < pr; ++i) z(i, k) = coin(rng) ? 1.0 : -1.0;
  }
  const Eigen::MatrixXd h_z = solver.SolveColumns(Eigen::MatrixXd(AtA * z));
  double trace = 0;
  for (int k = 0; k < o.trace_probes; ++k) trace += z.col(k).dot(h_z.col(k));
  return o.trace_probes > 0 ? trace / o.trace_probes : 0.0;
}

}  // namespace

SplineFit FitSplineToSlopes(const std::vector<Eigen::Vector2d>& points_mm, const std::vector<Eigen::Vector2d>& slopes,
                            double lambda, const SplineFitOptions& o, BSplineSurface* spline) {
  return SplineSlopeFitter().Fit(points_mm, slopes, lambda, o, spline);
}

void SplineSlopeFitter::BuildPattern(const std::vector<int>& index, int side, int pr, int penalty_order) {
  const int p = static_cast<int>(index.size());
  // Pattern of M = A^T A + lambda P + ridge I (both triangles: the products below use it): every pair of
  // unknowns at most w = max(3, order) grid steps apart along both axes, built column by column in CSC (a point
  // couples coefficients up to 3 apart, a difference row up to `order` apart along an axis). Structural zeros
  // where no point couples a pair change no value; building it directly is ~30 times cheaper than summing the
  // points' 160 k products as triplets. local_ gives the place of each neighbour in a column's values.
  const int w = std::max(3, penalty_order), span = 2 * w + 1;
  std::vector<int> grid_of(pr);
  for (int i = 0; i < p; ++i) {
    if (index[i] >= 0) grid_of[index[i]] = i;
  }
  local_.assign(static_cast<size_t>(pr) * span * span, -1);
  std::vector<int> outer(pr + 1, 0), inner;
  inner.reserve(static_cast<size_t>(pr) * span * span);
  band_ = 0;
  for (int u = 0; u < pr; ++u) {
    const int row = grid_of[u] / side, col = grid_of[u] % side;
    for (int dr = -w; dr <= w; ++dr) {
      for (int dc = -w; dc <= w; ++dc) {
        const int r2 = row + dr, c2 = col + dc;
        if (r2 < 0 || r2 >= side || c2 < 0 || c2 >= side || index[r2 * side + c2] < 0) continue;
        local_[(static_cast<size_t>(u) * span + dr + w) * span + dc + w] = static_cast<int>(inner.size());
        inner.push_back(index[r2 * side + c2]);  // ascending: index[] grows in grid order
      }
    }
    outer[u + 1] = static_cast<int>(inner.size());
    band_ = std::max(band_, inner.back() - u);  // rows ascend: the last is the farthest below the diagonal
  }
  const int nnz = static_cast<int>(inner.size());
  m_.resize(pr, pr);
  m_.resizeNonZeros(nnz);
  std::copy(outer.begin(), outer.end(), m_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), m_.innerIndexPtr());
  std::fill(m_.valuePtr(), m_.valuePtr() + nnz, 0.0);
  span_ = span;
  half_span_ = w;
  grid_of_ = std::move(grid_of);
  const SparseMatrix penalty = DifferencePenalty(side, penalty_order, index, pr);
  penalty_values_.assign(nnz, 0.0);
  for (int j = 0; j < penalty.outerSize(); ++j) {
    for (SparseMatrix::InnerIterator it(penalty, j); it; ++it) penalty_values_[Place(it.row(), it.col(), side)] = it.value();
  }
  diagonal_.resize(pr);
  for (int j = 0; j < pr; ++j) diagonal_[j] = Place(j, j, side);
  ata_values_.resize(nnz);
}

Eigen::VectorXd SplineSlopeFitter::AssembleNormalEquations(const Observations& obs) {
  // A^T A on the pattern and A^T b, from each point's 16 basis gradients (A itself is never formed).
  std::fill(ata_values_.begin(), ata_values_.end(), 0.0);
  Eigen::VectorXd Atb = Eigen::VectorXd::Zero(obs.unknowns);
  for (int k = 0; k < obs.n; ++k) {
    const double* ax = &obs.weight_x[16 * k];
    const double* ay = &obs.weight_y[16 * k];
    // The 16 coefficients are a 4 x 4 block of the grid, at most 3 steps apart along either axis.
    for (int a = 0; a < 16; ++a) {
      const int column = obs.index[obs.stencil[16 * k + a]];
      const int* local = &local_[(static_cast<size_t>(column) * span_ + half_span_) * span_ + half_span_];
      for (int b = 0; b < 16; ++b) {
        // row b relative to column a: (b / 4 - a / 4) grid rows, (b % 4 - a % 4) grid columns.
        ata_values_[local[(b / 4 - a / 4) * span_ + (b % 4 - a % 4)]] += ax[a] * ax[b] + ay[a] * ay[b];
      }
      Atb(obs.index[obs.stencil[16 * k + a]]) += ax[a] * obs.slopes[k].x() + ay[a] * obs.slopes[k].y();
    }
  }
  return Atb;
}

bool SplineSlopeFitter::SolveAt(int slot, double lam, double ridge, const Eigen::VectorXd& Atb, Eigen::VectorXd* c) {
  // M(lam) into m_'s values.
  const int nnz = static_cast<int>(m_.nonZeros());
  const int pr = static_cast<int>(diagonal_.size());
  double* v = m_.valuePtr();
  for (int i = 0; i < nnz; ++i) v[i] = ata_values_[i] + lam * penalty_values_[i];
  for (int j = 0; j < pr; ++j) v[diagonal_[j]] += ridge;
  // Factorises M(lam) into `slot` and solves for c.
  BandCholesky& solver = solvers_[slot];
  ++factorisations_;
  if (!solver.Factorize(m_, band_)) return false;
  *c = solver.Solve(Atb);
  return c->allFinite();
}

bool SplineSlopeFitter::ChooseLambdaByReml(const Observations& obs, const Eigen::VectorXd& Atb, double scale,
                                           double ridge, const SplineFitOptions& o, SplineFit* fit,
                                           Eigen::VectorXd* c) {
  // lambda by restricted maximum likelihood (REML) over a log grid. With c ~ N(0, sigma^2 / lambda P^-) and
  // sigma^2 profiled out, -2 log L_R = (m - nu) log(RSS + lambda c'Pc) + log det M - (p - nu) log lambda + const
  // (nu = order^2: the penalty's null space, polynomials of degree < order in x and in y). log det M is the sum
  // of log D of the LDL^T factor: one factorisation per lambda and no trace. It replaced GCV with a Hutchinson
  // trace (docs/reconstruction.md, "The spline's cost"): GCV, even with the exact trace, has its global minimum
  // at the interpolating end of the grid on the hyperopic +6 D ablation (axial max 2.5 D) and was kept off it
  // only by the estimator's noise; REML chose a lambda that holds the whole test set, exact and noisy.
  const int pr = obs.unknowns;
  const int nnz = static_cast<int>(m_.nonZeros());
  const Eigen::Map<const SparseMatrix> P(pr, pr, nnz, m_.outerIndexPtr(), m_.innerIndexPtr(), penalty_values_.data());
  const double m = 2.0 * obs.n;
  const int null_dim = o.penalty_order * o.penalty_order;
  std::vector<double> grid;  // lambda / scale, from the smoothest end
  for (double rel = o.lambda_max; rel >= o.lambda_min * 0.9999; rel /= o.lambda_step) grid.push_back(rel);
  if (grid.empty()) return false;
  std::vector<double> reml(grid.size(), NAN);
  double best_reml = INFINITY;
  int best_index = -1;
  // REML at grid point i (factorised into the slot that does not hold the best so far); infinite where it fails.
  const auto evaluate = [&](int i) {
    if (!std::isnan(reml[i])) return reml[i];
    const double lam = grid[i] * scale;
    const int slot = best_index < 0 ? best_ : 1 - best_;
    Eigen::VectorXd ci;
    double value = INFINITY;
    if (SolveAt(slot, lam, ridge, Atb, &ci)) {
      const double fit_and_penalty = obs.ResidualSum(ci) + lam * ci.dot(P * ci);
      const double log_det = solvers_[slot].LogDeterminant();
      if (fit_and_penalty > 0 && std::isfinite(log_det)) {
        value = (m - null_dim) * std::log(fit_and_penalty) + log_det - (pr - null_dim) * std::log(lam);
      }
    }
    reml[i] = value;
    if (value < best_reml) {
      best_reml = value;
      best_index = i;
      best_ = slot;
      fit->lambda = lam;
      *c = std::move(ci);
    }
    return value;
  };
  // The walk: from the grid point nearest lambda_start towards the smaller criterion while it falls — 3
  // factorisations when the minimum is at the start, instead of one per grid point. Where REML over the grid has
  // one minimum the walk ends there; on the freeform test set it chose what the whole grid chose (the table is
  // unchanged to the printed digits, docs/reconstruction.md).
  int start = 0;
  for (int i = 1; i < static_cast<int>(grid.size()); ++i) {
    if (std::abs(std::log(grid[i] / o.lambda_start)) < std::abs(std::log(grid[start] / o.lambda_start))) start = i;
  }
  evaluate(start);
  for (int direction : {-1, +1}) {
    for (int i = start + direction; i >= 0 && i < static_cast<int>(grid.size()); i += direction) {
      if (!(evaluate(i) < evaluate(i - direction))) break;
    }
    if (best_index != start) break;  // the criterion fell this way: the other way rises from the start
  }
  return std::isfinite(best_reml);
}

SplineFit SplineSlopeFitter::Fit(const std::vector<Eigen::Vector2d>& points_mm,
                                 const std::vector<Eigen::Vector2d>& slopes, double lambda, const SplineFitOptions& o,
                                 BSplineSurface* spline) {
  SplineFit fit;
  const int n = static_cast<int>(points_mm.size());
  const int p = spline->unknowns();
  if (n == 0 || slopes.size() != points_mm.size() || p == 0) return fit;
  const int side = static_cast<int>(std::lround(std::sqrt(p)));
  // The unknowns: the coefficients whose support holds a point, and support_margin rings of coefficients around
  // them (the rest of the square grid, ~1/3 of it around a disc of spots, is shaped by nothing but the penalty
  // and is set to 0: the analysis never uses the spline beyond the data). Half the unknowns of the full grid,
  // a third of its factorisation time (docs/reconstruction.md, "The spline's cost").
  Observations obs(slopes, n);
  std::vector<char> touched(p, 0);
  for (int k = 0; k < n; ++k) {
    spline->GradientStencil(points_mm[k].x(), points_mm[k].y(), &obs.stencil[16 * k], &obs.weight_x[16 * k],
                            &obs.weight_y[16 * k]);
    for (int q = 0; q < 16; ++q) touched[obs.stencil[16 * k + q]] = 1;
  }
  obs.index.assign(p, -1);
  obs.unknowns = NumberUnknowns(touched, side, o.support_margin, &obs.index);
  const std::vector<int>& index = obs.index;
  // The sparsity pattern of M depends on the unknowns alone (below); while they stay (the refinement moves points
  // by micrometres) the pattern, the penalty on it and the symbolic analysis of each slot are kept.
  std::vector<int> key(index);
  key.push_back(o.penalty_order);
  const int pr = obs.unknowns;
  if (key != pattern_key_) {
    pattern_key_ = std::move(key);
    ++analyses_;
    BuildPattern(index, side, pr, o.penalty_order);
  }
  const Eigen::VectorXd Atb = AssembleNormalEquations(obs);
  const int nnz = static_cast<int>(m_.nonZeros());
  const Eigen::Map<const SparseMatrix> AtA(pr, pr, nnz, m_.outerIndexPtr(), m_.innerIndexPtr(), ata_values_.data());
  double trace_ata = 0, trace_p = 0;
  for (int j = 0; j < pr; ++j) trace_ata += ata_values_[diagonal_[j]], trace_p += penalty_values_[diagonal_[j]];
  // The constant (and, for order >= 2, more) is in the null space of both the slopes and the penalty: a ridge far
  // below either term fixes it (the piston is then set explicitly).
  const double scale = trace_ata / std::max(1e-300, trace_p);
  const double ridge = 1e-12 * trace_ata / pr;
  Eigen::VectorXd c;
  if (lambda < 0) {
    if (!ChooseLambdaByReml(obs, Atb, scale, ridge, o, &fit, &c)) return fit;
    // tr H at the chosen lambda, on its kept factorisation.
    fit.effective_params = EffectiveParameters(solvers_[best_], AtA, pr, o);
  } else {
    // A refit at a given lambda: a direct solve of its own M on the kept analysis (a refit by conjugate gradients
    // preconditioned with the previous factorisation differed from a fresh solve by up to 7e-6 relative on these
    // unknowns, docs/reconstruction.md).
    fit.lambda = lambda;
    if (!SolveAt(best_, lambda, ridge, Atb, &c)) return fit;
  }
  Eigen::VectorXd& coefficients = spline->coefficients();
  for (int i = 0; i < p; ++i) coefficients(i) = index[i] >= 0 ? c(index[i]) : 0.0;
  // Piston: B(0, 0) = 0 (the basis is a partition of unity).
  spline->coefficients().array() -= spline->Value(0.0, 0.0);
  fit.rms_slope_residual = std::sqrt(obs.ResidualSum(c) / (2.0 * n));
  fit.ok = true;
  return fit;
}

}  // namespace topocal::topo
