#include "topo/sphere_fit.h"

#include <algorithm>
#include <cmath>

#include <ceres/ceres.h>
#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <fmt/format.h>

#include "topo/surface_fit_solver.h"

namespace topocal::topo {
namespace {

// Parameter vector: centre x, y, z (mm), radius (mm).
constexpr int kNumParams = 4;

// All the points' orthogonal distances in one residual block with the analytic Jacobian
// d_i = |p_i - c| - r:  dd_i/dc = -(p_i - c) / |p_i - c|,  dd_i/dr = -1.
// One block rather than one per point: the problem has thousands of points and 4 parameters, and per-block
// overhead (and autodiff) would cost more than the arithmetic.
class SphereDistances final : public ceres::CostFunction {
 public:
  explicit SphereDistances(const std::vector<Eigen::Vector3d>& points_mm) : points_(points_mm) {
    set_num_residuals(static_cast<int>(points_.size()));
    mutable_parameter_block_sizes()->push_back(kNumParams);
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const double* q = parameters[0];
    const Eigen::Vector3d c(q[0], q[1], q[2]);
    for (size_t i = 0; i < points_.size(); ++i) {
      const Eigen::Vector3d d = points_[i] - c;
      const double dist = d.norm();
      // A point at the centre has no direction: reject the step rather than divide by zero.
      if (!(dist > 0)) return false;
      residuals[i] = dist - q[3];
      if (jacobians && jacobians[0]) {
        double* row = jacobians[0] + kNumParams * i;
        row[0] = -d.x() / dist;
        row[1] = -d.y() / dist;
        row[2] = -d.z() / dist;
        row[3] = -1.0;
      }
    }
    return true;
  }

 private:
  const std::vector<Eigen::Vector3d>& points_;
};

// The sag residual r_i = z_i - (c_z - sqrt(A_i)), A_i = r^2 - (x_i - c_x)^2 - (y_i - c_y)^2, of the cap facing the
// camera, and its Jacobian row dr/dc_x = (x_i - c_x) / sqrt(A_i), dr/dc_y = (y_i - c_y) / sqrt(A_i), dr/dc_z = -1,
// dr/dr = r / sqrt(A_i), at q = (c_x, c_y, c_z, r); false beyond the sphere's equator (the sag is undefined there).
bool SagResidual(const Eigen::Vector3d& p, const double* q, double* residual, double* row) {
  const double dx = p.x() - q[0], dy = p.y() - q[1];
  const double arg = q[3] * q[3] - dx * dx - dy * dy;
  if (!(arg > 0)) return false;
  const double root = std::sqrt(arg);
  *residual = p.z() - (q[2] - root);
  row[0] = dx / root;
  row[1] = dy / root;
  row[2] = -1.0;
  row[3] = q[3] / root;
  return true;
}

// Kasa's algebraic fit: |p|^2 + D.p + E = 0 is linear in (D, E); c = -D/2, r^2 = |c|^2 - E. Exact for points on a
// sphere; under noise a fine start (its bias is O(noise^2 / r)).
bool AlgebraicStart(const std::vector<Eigen::Vector3d>& pts, double* q) {
  Eigen::MatrixXd A(pts.size(), 4);
  Eigen::VectorXd b(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const auto& p = pts[i];
    A.row(static_cast<Eigen::Index>(i)) << p.x(), p.y(), p.z(), 1.0;
    b(static_cast<Eigen::Index>(i)) = -p.squaredNorm();
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 4) return false;
  const Eigen::Vector4d s = qr.solve(b);
  const Eigen::Vector3d c = -0.5 * s.head<3>();
  const double r2 = c.squaredNorm() - s(3);
  if (!(r2 > 0) || !std::isfinite(r2)) return false;
  q[0] = c.x();
  q[1] = c.y();
  q[2] = c.z();
  q[3] = std::sqrt(r2);
  return true;
}

// The sag fit by Gauss-Newton steps on the 4 x 4 normal equations, in Eigen: the clinical best-fit
// sphere of every analysis is ~2,900 points in 4 parameters started at Kasa's fit, well inside the quadratic region,
// and Ceres' per-iteration machinery (program evaluator, jacobian writer, column scaling, array validation) cost more
// than the arithmetic. Stops like SurfaceFitSolverOptions: when the cost changes by <= 1e-12 of itself or the step is
// <= 1e-13 of the parameter norm. A step that raises the cost or crosses a point's equator is halved (never needed
// from Kasa's start on a corneal cap; it keeps the fit from leaving the region where the sag is defined). Returns
// the iterations taken (every evaluated step counts, as Ceres counts its iterations) and the final cost
// (1/2 sum of squares, Ceres' convention); false if the start itself is invalid or J^T J is singular.
bool FitSagGaussNewton(const std::vector<Eigen::Vector3d>& pts, int max_iterations, double* q, int* iterations,
                       double* final_cost) {
  // The cost at q and, when asked, J^T J and J^T r; false beyond a point's equator.
  const auto evaluate = [&pts](const double* at, double* cost, Eigen::Matrix4d* jtj, Eigen::Vector4d* jtr) {
    double sum2 = 0;
    if (jtj) jtj->setZero(), jtr->setZero();
    for (const auto& p : pts) {
      double r;
      Eigen::Vector4d row;
      if (!SagResidual(p, at, &r, row.data())) return false;
      sum2 += r * r;
      if (jtj) {
        jtj->selfadjointView<Eigen::Lower>().rankUpdate(row);
        *jtr += r * row;
      }
    }
    *cost = 0.5 * sum2;
    return true;
  };
  double cost;
  Eigen::Matrix4d jtj;
  Eigen::Vector4d jtr;
  *iterations = 0;
  if (!evaluate(q, &cost, &jtj, &jtr)) return false;
  while (*iterations < max_iterations) {
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(jtj);  // lower triangle only
    // A singular J^T J: the points do not determine the sphere (no fit rather than the start reported as one).
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || !(ldlt.vectorD().minCoeff() > 0)) return false;
    Eigen::Vector4d step = -ldlt.solve(jtr);
    const Eigen::Map<Eigen::Vector4d> x(q);
    Eigen::Vector4d trial;
    double trial_cost = INFINITY;
    bool accepted = false;
    for (int halvings = 0; halvings < 30 && *iterations < max_iterations; ++halvings, step *= 0.5) {
      ++*iterations;
      trial = x + step;
      if (evaluate(trial.data(), &trial_cost, nullptr, nullptr) && trial_cost <= cost) {
        accepted = true;
        break;
      }
    }
    if (!accepted) break;
    const bool small_step = step.norm() <= (x.norm() + 1e-13) * 1e-13;
    const bool small_change = cost - trial_cost <= 1e-12 * cost;
    std::copy(trial.data(), trial.data() + kNumParams, q);
    if (small_step || small_change) {
      cost = trial_cost;
      break;
    }
    if (!evaluate(q, &cost, &jtj, &jtr)) return false;
  }
  *final_cost = cost;
  return std::isfinite(cost);
}

}  // namespace

model::Sphere SphereFit::AsSurface() const {
  model::Sphere s;
  s.radius_mm = radius_mm;
  s.x0_mm = centre_mm.x();
  s.y0_mm = centre_mm.y();
  s.z0_mm = centre_mm.z() - radius_mm;
  return s;
}

SphereFit FitSphere(const std::vector<Eigen::Vector3d>& points_mm, const SphereFitOptions& options) {
  SphereFit fit;
  fit.points = static_cast<int>(points_mm.size());
  if (fit.points < kNumParams + 1) {
    fit.message = fmt::format("{} points cannot determine a sphere (centre and radius need at least {})", fit.points,
                              kNumParams + 1);
    return fit;
  }
  double q[kNumParams];
  if (options.start && options.start->ok) {
    q[0] = options.start->centre_mm.x();
    q[1] = options.start->centre_mm.y();
    q[2] = options.start->centre_mm.z();
    q[3] = options.start->radius_mm;
  } else if (!AlgebraicStart(points_mm, q)) {
    fit.message = "the points do not determine a sphere (they lie on a plane or a circle)";
    return fit;
  }
  const bool sag = options.residual == SphereResidual::kSag;
  double final_cost = 0;
  if (sag) {
    if (!FitSagGaussNewton(points_mm, options.max_iterations, q, &fit.iterations, &final_cost) || !(q[3] > 0)) {
      fit.message =
          "sphere fit failed: the sag is undefined (a point beyond the sphere's equator), not finite, or "
          "the points do not determine the sphere";
      return fit;
    }
  } else {
    ceres::Problem problem;
    problem.AddResidualBlock(new SphereDistances(points_mm), nullptr, q);
    // The problem is well conditioned (4 parameters, thousands of points): the shared tight tolerances are met in
    // a handful of iterations.
    const ceres::Solver::Options so = options.start && options.start->ok
                                          ? WarmStartSolverOptions(options.max_iterations)
                                          : SurfaceFitSolverOptions(options.max_iterations);
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    fit.iterations = static_cast<int>(summary.iterations.size());
    if (!summary.IsSolutionUsable() || !(q[3] > 0) || !std::isfinite(summary.final_cost)) {
      fit.message = fmt::format("sphere fit failed: {}", summary.message);
      return fit;
    }
    final_cost = summary.final_cost;
  }
  fit.centre_mm = Eigen::Vector3d(q[0], q[1], q[2]);
  fit.radius_mm = q[3];
  const double ssr = 2.0 * final_cost;
  fit.rms_residual_um = std::sqrt(ssr / fit.points) * 1e3;

  if (options.stddev) {
    // Covariance (J'J)^-1 SSR / (n - 4), from the Jacobian at the solution.
    Eigen::Matrix4d jtj = Eigen::Matrix4d::Zero();
    for (const auto& p : points_mm) {
      Eigen::Vector4d row;
      if (sag) {
        double unused;
        if (!SagResidual(p, q, &unused, row.data())) continue;
      } else {
        const Eigen::Vector3d d = p - fit.centre_mm;
        row << -d / d.norm(), -1.0;
      }
      jtj.selfadjointView<Eigen::Lower>().rankUpdate(row);
    }
    jtj.triangularView<Eigen::StrictlyUpper>() = jtj.transpose();
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(jtj);
    if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
      const Eigen::Matrix4d cov = ldlt.solve(Eigen::Matrix4d::Identity()) * (ssr / (fit.points - kNumParams));
      fit.centre_stddev_mm = cov.diagonal().head<3>().cwiseMax(0.0).cwiseSqrt();
      fit.radius_stddev_mm = std::sqrt(std::max(0.0, cov(3, 3)));
      fit.vertex_z_stddev_mm = std::sqrt(std::max(0.0, cov(2, 2) + cov(3, 3) - 2.0 * cov(2, 3)));
      fit.stddev_ok = cov.allFinite();
    }
  }
  fit.ok = true;
  fit.message = fmt::format("sphere fit ({}): {} points, rms {:.3g} um, {} iterations, radius {:.4f} mm, centre "
                            "({:.4f}, {:.4f}, {:.4f}) mm",
                            sag ? "sag" : "orthogonal", fit.points, fit.rms_residual_um, fit.iterations, fit.radius_mm, fit.centre_mm.x(),
                            fit.centre_mm.y(), fit.centre_mm.z());
  return fit;
}

}  // namespace topocal::topo
