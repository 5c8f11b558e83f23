#include "topo/biconic_fit.h"

#include <cmath>

#include <ceres/ceres.h>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <fmt/format.h>

namespace topocal::topo {
namespace {

enum Param : int { kCx = 0, kCy, kKx, kKy, kAlpha, kZ0, kX0, kY0, kNumParams };

struct BiconicSagResidual {
  BiconicSagResidual(const Eigen::Vector3d& p) : x_mm(p.x()), y_mm(p.y()), z_mm(p.z()) {}

  template <typename T>
  bool operator()(const T* const q, T* residual) const {
    using std::cos;
    using std::sin;
    using std::sqrt;
    const T ca = cos(q[kAlpha]), sa = sin(q[kAlpha]);
    const T X = ca * x_mm + sa * y_mm - q[kX0];
    const T Y = -sa * x_mm + ca * y_mm - q[kY0];
    const T arg = T(1) - (T(1) + q[kKx]) * q[kCx] * q[kCx] * X * X - (T(1) + q[kKy]) * q[kCy] * q[kCy] * Y * Y;
    // Outside the biconic's domain: a large residual steers the solver back instead of producing NaN.
    if (!(arg > T(0))) return false;
    residual[0] = T(z_mm) - (q[kZ0] + (q[kCx] * X * X + q[kCy] * Y * Y) / (T(1) + sqrt(arg)));
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& p) {
    return new ceres::AutoDiffCostFunction<BiconicSagResidual, 1, kNumParams>(new BiconicSagResidual(p));
  }

  double x_mm, y_mm, z_mm;
};

// Initial guess from a quadratic fit z ~ z0 + a x + b y + c x^2 + d xy + e y^2 to the central points: the
// eigen-decomposition of the Hessian gives the vertex curvatures and the rotation.
bool InitialGuess(const std::vector<Eigen::Vector3d>& pts, double* q) {
  double rmax = 0;
  for (const auto& p : pts) rmax = std::max(rmax, p.head<2>().norm());
  const double central = 0.5 * rmax;
  std::vector<const Eigen::Vector3d*> use;
  for (const auto& p : pts) if (p.head<2>().norm() <= central) use.push_back(&p);
  if (use.size() < 12) {
    use.clear();
    for (const auto& p : pts) use.push_back(&p);
  }
  Eigen::MatrixXd A(use.size(), 6);
  Eigen::VectorXd b(use.size());
  for (size_t i = 0; i < use.size(); ++i) {
    const auto& p = *use[i];
    A.row(i) << 1, p.x(), p.y(), p.x() * p.x(), p.x() * p.y(), p.y() * p.y();
    b(i) = p.z();
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 6) return false;
  const Eigen::VectorXd s = qr.solve(b);
  Eigen::Matrix2d H;
  H << 2 * s(3), s(4), s(4), 2 * s(5);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(H);
  const double c_small = es.eigenvalues()(0), c_large = es.eigenvalues()(1);
  if (!(c_small > 0)) return false;
  const Eigen::Vector2d dir = es.eigenvectors().col(0);  // flatter meridian (larger radius) -> r_x
  q[kCx] = c_small;
  q[kCy] = c_large;
  q[kKx] = q[kKy] = 0.0;
  q[kAlpha] = std::atan2(dir.y(), dir.x());
  q[kZ0] = s(0);
  q[kX0] = q[kY0] = 0.0;
  return true;
}

double WrapDegrees180(double a) {
  a = std::fmod(a, 180.0);
  if (a < 0) a += 180.0;
  if (a >= 180.0) a -= 180.0;
  return a;
}

}  // namespace

model::BiconicParams CanonicalBiconic(const model::BiconicParams& p) {
  model::BiconicParams c = p;
  if (c.rx_mm < c.ry_mm) {
    // Rotating the frame by 90 deg: X' = Y, Y' = -X.
    std::swap(c.rx_mm, c.ry_mm);
    std::swap(c.kx, c.ky);
    c.alpha_deg += 90.0;
    const double x0 = c.x0_mm;
    c.x0_mm = c.y0_mm;
    c.y0_mm = -x0;
  }
  const double wrapped = WrapDegrees180(c.alpha_deg);
  // A half-turn maps (X, Y) to (-X, -Y): the decentration changes sign.
  if (std::abs(std::fmod(c.alpha_deg - wrapped, 360.0)) > 1.0) {
    c.x0_mm = -c.x0_mm;
    c.y0_mm = -c.y0_mm;
  }
  c.alpha_deg = wrapped;
  return c;
}

BiconicFit FitBiconic(const std::vector<Eigen::Vector3d>& points_mm, const BiconicFitOptions& options) {
  BiconicFit fit;
  fit.points = static_cast<int>(points_mm.size());
  const int free_params = options.fit_decentration ? kNumParams : kNumParams - 2;
  if (fit.points < free_params + 1) {
    fit.message = fmt::format("{} points cannot determine {} biconic parameters", fit.points, free_params);
    return fit;
  }
  double q[kNumParams];
  if (!InitialGuess(points_mm, q)) {
    fit.message = "the point cloud is not a convex cap (no positive vertex curvature)";
    return fit;
  }
  ceres::Problem problem;
  for (const auto& p : points_mm) problem.AddResidualBlock(BiconicSagResidual::Create(p), nullptr, q);
  if (!options.fit_decentration) {
    problem.SetManifold(q, new ceres::SubsetManifold(kNumParams, {kX0, kY0}));
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  // Tight tolerances: the cloud is exact to nanometres and the conic constants are weakly determined.
  so.function_tolerance = 1e-16;
  so.gradient_tolerance = 1e-16;
  so.parameter_tolerance = 1e-14;
  so.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  fit.iterations = static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable() || !(q[kCx] > 0) || !(q[kCy] > 0)) {
    fit.message = fmt::format("biconic fit failed: {}", summary.message);
    return fit;
  }
  const double ssr = 2.0 * summary.final_cost;
  fit.rms_residual_um = std::sqrt(ssr / fit.points) * 1e3;

  model::BiconicParams p;
  p.rx_mm = 1.0 / q[kCx];
  p.ry_mm = 1.0 / q[kCy];
  p.kx = q[kKx];
  p.ky = q[kKy];
  p.alpha_deg = q[kAlpha] * 180.0 / M_PI;
  p.z0_mm = q[kZ0];
  p.x0_mm = q[kX0];
  p.y0_mm = q[kY0];

  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;  // drop directions below min_reciprocal_condition_number instead of failing
  ceres::Covariance covariance(co);
  std::vector<std::pair<const double*, const double*>> blocks = {{q, q}};
  if (covariance.Compute(blocks, &problem)) {
    double cov[kNumParams * kNumParams];
    covariance.GetCovarianceBlockInTangentSpace(q, q, cov);
    const int dof = std::max(1, fit.points - free_params);
    const double s2 = ssr / dof;
    // Tangent-space order skips the fixed x0, y0.
    const auto var = [&](int i) { return std::max(0.0, cov[i * free_params + i]) * s2; };
    auto& sd = fit.stddev;
    sd.rx_mm = std::sqrt(var(kCx)) / (q[kCx] * q[kCx]);
    sd.ry_mm = std::sqrt(var(kCy)) / (q[kCy] * q[kCy]);
    sd.kx = std::sqrt(var(kKx));
    sd.ky = std::sqrt(var(kKy));
    sd.alpha_deg = std::sqrt(var(kAlpha)) * 180.0 / M_PI;
    sd.z0_mm = std::sqrt(var(kZ0));
    if (options.fit_decentration) {
      sd.x0_mm = std::sqrt(var(kX0));
      sd.y0_mm = std::sqrt(var(kY0));
    }
    fit.stddev_ok = true;
  }
  const bool swapped = p.rx_mm < p.ry_mm;
  fit.params = CanonicalBiconic(p);
  if (swapped) {
    std::swap(fit.stddev.rx_mm, fit.stddev.ry_mm);
    std::swap(fit.stddev.kx, fit.stddev.ky);
    std::swap(fit.stddev.x0_mm, fit.stddev.y0_mm);
  }
  fit.ok = true;
  fit.message = fmt::format("{} points, rms {:.3g} um, {} iterations", fit.points, fit.rms_residual_um, fit.iterations);
  return fit;
}

}  // namespace topocal::topo
