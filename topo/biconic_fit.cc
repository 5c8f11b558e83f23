#include "topo/biconic_fit.h"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "model/surface.h"
#include "topo/biconic_jacobian.h"
#include "topo/sphere_fit.h"
#include "topo/surface_fit_solver.h"
#include "util/io.h"

namespace topocal::topo {
namespace {

using K = model::BiconicKernel;

// All the points' sag residuals z_i - S(x_i, y_i) in one residual block with the closed-form Jacobian of
// topo/biconic_jacobian.h. One block rather than one per point, so that the trigonometry and the rotation are
// computed once per evaluation instead of once per point, and Ceres' per-block overhead is paid once.
// Ceres' trust region evaluates the cost at a candidate and, when it accepts it, the Jacobian at the same
// parameters: the sags of the last cost-only evaluation are kept and reused then, so that the tilted surface's
// Newton root is found once per point and step, not twice. Reuse needs the parameters bit for bit equal, so the
// values are the ones an evaluation at these parameters gave. (The solver runs on one thread:
// SurfaceFitSolverOptions.) A new candidate's tilted roots start from the kept sags (BiconicSagJacobian::SagNear):
// one or two Newton steps per point instead of five, the same roots to a few ulps (docs/performance.md).
// With keep_jacobian, the Jacobian of the last evaluation that computed one is kept too: Ceres' last one is at the
// solution, where the covariance needs it (FitCovariance), so the covariance costs no evaluation of its own.
class BiconicSagResiduals final : public ceres::CostFunction {
 public:
  BiconicSagResiduals(const std::vector<Eigen::Vector3d>& points_mm, bool tilted, bool keep_jacobian)
      : points_(points_mm), tilted_(tilted), keep_jacobian_(keep_jacobian), sag_mm_(points_mm.size()) {
    set_num_residuals(static_cast<int>(points_.size()));
    mutable_parameter_block_sizes()->push_back(K::kNumParams);
  }
  // The Jacobian (row-major, num_residuals x kNumParams) kept at exactly these parameters, or null.
  const double* KeptJacobianAt(const double* q) const {
    return jacobian_valid_ && std::equal(q, q + K::kNumParams, jacobian_q_) ? kept_jacobian_.data() : nullptr;
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const double* q = parameters[0];
    const BiconicSagJacobian surface(q, tilted_);
    double* jacobian = jacobians ? jacobians[0] : nullptr;
    const bool reuse = sags_valid_ && std::equal(q, q + K::kNumParams, sag_q_);
    // Otherwise each tilted root starts from the last evaluation's sag of its point, when that evaluation
    // succeeded: Ceres' steps near the optimum are small, and one Newton step then finds the root.
    const bool warm = sags_valid_;
    sags_valid_ = false;
    for (size_t i = 0; i < points_.size(); ++i) {
      const Eigen::Vector3d& p = points_[i];
      // Outside the biconic's domain: Ceres rejects the step instead of seeing NaN.
      if (!reuse &&
          !(warm ? surface.SagNear(p.x(), p.y(), sag_mm_[i], &sag_mm_[i]) : surface.Sag(p.x(), p.y(), &sag_mm_[i]))) {
        return false;
      }
      residuals[i] = p.z() - sag_mm_[i];
      if (jacobian) {
        double dz_dq[K::kNumParams];
        if (!surface.Derivatives(p.x(), p.y(), sag_mm_[i], dz_dq)) return false;
        double* row = jacobian + K::kNumParams * i;
        for (int j = 0; j < K::kNumParams; ++j) row[j] = -dz_dq[j];
      }
    }
    std::copy(q, q + K::kNumParams, sag_q_);
    sags_valid_ = true;
    if (jacobian && keep_jacobian_) {
      kept_jacobian_.assign(jacobian, jacobian + K::kNumParams * points_.size());
      std::copy(q, q + K::kNumParams, jacobian_q_);
      jacobian_valid_ = true;
    }
    return true;
  }

 private:
  const std::vector<Eigen::Vector3d>& points_;
  bool tilted_;
  bool keep_jacobian_;
  // The Jacobian of the last successful evaluation that computed one, and its parameters (keep_jacobian).
  mutable std::vector<double> kept_jacobian_;
  mutable double jacobian_q_[K::kNumParams] = {};
  mutable bool jacobian_valid_ = false;
  // The sags of the last successful evaluation and its parameters.
  mutable std::vector<double> sag_mm_;
  mutable double sag_q_[K::kNumParams] = {};
  mutable bool sags_valid_ = false;
};

// Initial guess from a quadratic fit z ~ z0 + a x + b y + c x^2 + d xy + e y^2 to the central points: the
// eigen-decomposition of the Hessian gives the vertex curvatures and the rotation, its stationary point the apex
// (free-apex mode; the tilt starts at zero and the fit separates it from the decentration).
bool InitialGuess(const std::vector<Eigen::Vector3d>& pts, bool free_apex, double* q) {
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
  q[K::kCx] = c_small;
  q[K::kCy] = c_large;
  q[K::kKx] = q[K::kKy] = 0.0;
  q[K::kAlpha] = std::atan2(dir.y(), dir.x());
  q[K::kX0] = q[K::kY0] = 0.0;
  q[K::kTiltX] = q[K::kTiltY] = 0.0;
  q[K::kZ0] = s(0);
  if (free_apex) {
    const Eigen::Vector2d apex = H.ldlt().solve(-Eigen::Vector2d(s(1), s(2)));
    const double ca = std::cos(q[K::kAlpha]), sa = std::sin(q[K::kAlpha]);
    q[K::kX0] = ca * apex.x() + sa * apex.y();
    q[K::kY0] = -sa * apex.x() + ca * apex.y();
    q[K::kZ0] = s(0) + 0.5 * Eigen::Vector2d(s(1), s(2)).dot(apex);
  }
  return true;
}

// The covariance (J^T J)^+ of the parameters from the Jacobian J at the solution, over the free parameters (the
// ones a "paper" fit holds fixed get zero rows and columns), computed as ceres::Covariance's DENSE_SVD did it
// (the algorithm the fit used before; docs/performance.md): the SVD J = U S V^T, and directions whose
// singular value is below sqrt(1e-14) of the largest dropped (a pseudo-inverse, as with null_space_rank = -1)
// instead of failing. Without Ceres' covariance machinery (a second program, evaluator and sparse Jacobian) and
// without U, which the covariance does not use. False if the Jacobian cannot be evaluated.
bool FitCovariance(const BiconicSagResiduals& residuals, const double* q, bool free_apex,
                   Eigen::Matrix<double, K::kNumParams, K::kNumParams>* cov) {
  using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const int n = residuals.num_residuals();
  RowMatrix jacobian(n, K::kNumParams);
  if (const double* kept = residuals.KeptJacobianAt(q)) {
    jacobian = Eigen::Map<const RowMatrix>(kept, n, K::kNumParams);
  } else {
    Eigen::VectorXd r(n);
    const double* parameters[] = {q};
    double* jacobians[] = {jacobian.data()};
    if (!residuals.Evaluate(parameters, r.data(), jacobians)) return false;
  }
  constexpr int kPaperFree[] = {K::kCx, K::kCy, K::kKx, K::kKy, K::kAlpha, K::kZ0};
  std::vector<int> free;
  for (int j = 0; j < K::kNumParams; ++j) {
    if (free_apex || std::find(std::begin(kPaperFree), std::end(kPaperFree), j) != std::end(kPaperFree)) {
      free.push_back(j);
    }
  }
  const int p = static_cast<int>(free.size());
  RowMatrix j_free(n, p);
  for (int c = 0; c < p; ++c) j_free.col(c) = jacobian.col(free[c]);
  const Eigen::JacobiSVD<RowMatrix> svd(j_free, Eigen::ComputeThinV);
  const Eigen::VectorXd& s = svd.singularValues();
  Eigen::VectorXd inverse_squared = Eigen::VectorXd::Zero(p);
  const double min_ratio = std::sqrt(1e-14);  // Ceres' default min_reciprocal_condition_number
  for (int i = 0; i < p && s(i) / s(0) >= min_ratio; ++i) inverse_squared(i) = 1.0 / (s(i) * s(i));
  const RowMatrix c = svd.matrixV() * inverse_squared.asDiagonal() * svd.matrixV().transpose();
  cov->setZero();
  for (int a = 0; a < p; ++a) {
    for (int b = 0; b < p; ++b) (*cov)(free[a], free[b]) = c(a, b);
  }
  return true;
}

double WrapDegrees180(double a) {
  a = std::fmod(a, 180.0);
  if (a < 0) a += 180.0;
  if (a >= 180.0) a -= 180.0;
  return a;
}

}  // namespace

BiconicFitMode BiconicFitModeFromName(const std::string& name) {
  if (name == "free-apex") return BiconicFitMode::kFreeApex;
  if (name == "paper") return BiconicFitMode::kPaper;
  if (name == "sphere") return BiconicFitMode::kSphere;
  throw util::InputError(
      fmt::format("biconic fit must be \"free-apex\", \"paper\" or \"sphere\" (got \"{}\")", name));
}

const char* BiconicFitModeName(BiconicFitMode mode) {
  switch (mode) {
    case BiconicFitMode::kPaper: return "paper";
    case BiconicFitMode::kSphere: return "sphere";
    case BiconicFitMode::kFreeApex: break;
  }
  return "free-apex";
}

double BiconicFit::TiltDeg() const {
  const double tx = params.tilt_x_deg * M_PI / 180.0, ty = params.tilt_y_deg * M_PI / 180.0;
  // The eye's axis R e_z with R = Ry(ty) Rx(tx) has z component cos(tx) cos(ty).
  return std::acos(std::clamp(std::cos(tx) * std::cos(ty), -1.0, 1.0)) * 180.0 / M_PI;
}

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

namespace {

// BiconicFitMode::kSphere: the sphere fit written as the biconic it is (biconic_fit.h says which numbers are fitted).
BiconicFit SphereAsBiconic(const std::vector<Eigen::Vector3d>& points_mm, const BiconicFitOptions& options) {
  SphereFitOptions so;
  so.stddev = options.stddev;
  SphereFit start;
  if (options.start) {
    start.ok = true;
    start.radius_mm = options.start->rx_mm;
    start.centre_mm =
        Eigen::Vector3d(options.start->x0_mm, options.start->y0_mm, options.start->z0_mm + start.radius_mm);
    so.start = &start;
  }
  const SphereFit s = FitSphere(points_mm, so);
  BiconicFit fit;
  fit.mode = BiconicFitMode::kSphere;
  fit.points = s.points;
  fit.message = s.message;
  if (!s.ok) return fit;
  auto& p = fit.params;
  p.rx_mm = p.ry_mm = s.radius_mm;
  p.kx = p.ky = 0.0;
  p.alpha_deg = 0.0;
  p.x0_mm = s.centre_mm.x();
  p.y0_mm = s.centre_mm.y();
  p.z0_mm = s.centre_mm.z() - s.radius_mm;
  p.tilt_x_deg = p.tilt_y_deg = 0.0;
  fit.apex_mm = Eigen::Vector3d(p.x0_mm, p.y0_mm, p.z0_mm);
  if (s.stddev_ok) {
    auto& sd = fit.stddev;
    sd.rx_mm = sd.ry_mm = s.radius_stddev_mm;
    sd.z0_mm = s.vertex_z_stddev_mm;
    sd.x0_mm = sd.apex_x_mm = s.centre_stddev_mm.x();
    sd.y0_mm = sd.apex_y_mm = s.centre_stddev_mm.y();
    fit.stddev_ok = true;
  }
  fit.rms_residual_um = s.rms_residual_um;
  fit.iterations = s.iterations;
  fit.ok = true;
  return fit;
}

// The biconic's standard deviations from the covariance of the kernel's parameters q (ambient space, scaled by the
// residual variance); the apex's by first-order propagation.
void StddevFromCovariance(const Eigen::Matrix<double, K::kNumParams, K::kNumParams>& cov, const double* q,
                          BiconicStdDev* stddev) {
  const auto sd = [&](int i) { return std::sqrt(std::max(0.0, cov(i, i))); };
  BiconicStdDev& s = *stddev;
  s.rx_mm = sd(K::kCx) / (q[K::kCx] * q[K::kCx]);
  s.ry_mm = sd(K::kCy) / (q[K::kCy] * q[K::kCy]);
  s.kx = sd(K::kKx);
  s.ky = sd(K::kKy);
  s.alpha_deg = sd(K::kAlpha) * 180.0 / M_PI;
  s.z0_mm = sd(K::kZ0);
  s.x0_mm = sd(K::kX0);
  s.y0_mm = sd(K::kY0);
  s.tilt_x_deg = sd(K::kTiltX) * 180.0 / M_PI;
  s.tilt_y_deg = sd(K::kTiltY) * 180.0 / M_PI;
  // apex = Rot(-alpha) (x0, y0): first-order propagation through (alpha, x0, y0).
  const double ca = std::cos(q[K::kAlpha]), sa = std::sin(q[K::kAlpha]);
  Eigen::Matrix<double, 2, 3> J;
  J << -sa * q[K::kX0] - ca * q[K::kY0], ca, -sa, ca * q[K::kX0] - sa * q[K::kY0], sa, ca;
  Eigen::Matrix3d c3;
  const int idx[3] = {K::kAlpha, K::kX0, K::kY0};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) c3(i, j) = cov(idx[i], idx[j]);
  const Eigen::Matrix2d ca2 = J * c3 * J.transpose();
  s.apex_x_mm = std::sqrt(std::max(0.0, ca2(0, 0)));
  s.apex_y_mm = std::sqrt(std::max(0.0, ca2(1, 1)));
}

}  // namespace

BiconicFit FitBiconic(const std::vector<Eigen::Vector3d>& points_mm, const BiconicFitOptions& options) {
  if (options.mode == BiconicFitMode::kSphere) return SphereAsBiconic(points_mm, options);
  BiconicFit fit;
  fit.mode = options.mode;
  fit.points = static_cast<int>(points_mm.size());
  const bool free_apex = options.mode == BiconicFitMode::kFreeApex;
  const int free_params = free_apex ? K::kNumParams : K::kNumParams - 4;
  if (fit.points < free_params + 1) {
    fit.message = fmt::format("{} points cannot determine {} biconic parameters", fit.points, free_params);
    return fit;
  }
  double q[K::kNumParams];
  if (options.start) {
    K::FromParams(*options.start, q);
    if (!free_apex) q[K::kX0] = q[K::kY0] = q[K::kTiltX] = q[K::kTiltY] = 0.0;
  } else if (!InitialGuess(points_mm, free_apex, q)) {
    fit.message = "the point cloud is not a convex cap (no positive vertex curvature)";
    return fit;
  }
  ceres::Problem problem;
  auto* residuals = new BiconicSagResiduals(points_mm, free_apex, options.stddev);  // owned by the problem
  problem.AddResidualBlock(residuals, nullptr, q);
  if (!free_apex) {
    problem.SetManifold(q, new ceres::SubsetManifold(K::kNumParams, {K::kX0, K::kY0, K::kTiltX, K::kTiltY}));
  }
  const ceres::Solver::Options so =
      options.start ? WarmStartSolverOptions(options.max_iterations) : SurfaceFitSolverOptions(options.max_iterations);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  fit.iterations = static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable() || !(q[K::kCx] > 0) || !(q[K::kCy] > 0)) {
    fit.message = fmt::format("biconic fit failed: {}", summary.message);
    return fit;
  }
  const double ssr = 2.0 * summary.final_cost;
  fit.rms_residual_um = std::sqrt(ssr / fit.points) * 1e3;
  const model::BiconicParams p = K::ToParams(q);

  Eigen::Matrix<double, K::kNumParams, K::kNumParams> cov;  // ambient space: zero where the fit holds fixed
  if (options.stddev && FitCovariance(*residuals, q, free_apex, &cov)) {
    const int dof = std::max(1, fit.points - free_params);
    cov *= ssr / dof;
    StddevFromCovariance(cov, q, &fit.stddev);
    fit.stddev_ok = true;
  }
  const bool swapped = p.rx_mm < p.ry_mm;
  fit.params = CanonicalBiconic(p);
  fit.apex_mm = model::Biconic{fit.params}.ApexMm();
  if (swapped) {
    std::swap(fit.stddev.rx_mm, fit.stddev.ry_mm);
    std::swap(fit.stddev.kx, fit.stddev.ky);
    std::swap(fit.stddev.x0_mm, fit.stddev.y0_mm);
  }
  fit.ok = true;
  fit.message = fmt::format("{} fit: {} points, rms {:.3g} um, {} iterations", BiconicFitModeName(options.mode),
                            fit.points, fit.rms_residual_um, fit.iterations);
  if (free_apex) {
    fit.message += fmt::format(", apex ({:.4f}, {:.4f}) mm, tilt {:.3f} deg", fit.apex_mm.x(), fit.apex_mm.y(), fit.TiltDeg());
  }
  return fit;
}

}  // namespace topocal::topo
