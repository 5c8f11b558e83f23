#include "calib/calibrate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <fmt/format.h>
#include <opencv2/calib3d.hpp>

#include "calib/cost_functions.h"
#include "calib/jacobian_covariance.h"
#include "model/distortion.h"

namespace topocal::calib {
namespace {

enum ParamIndex : int { kFx, kFy, kCx, kCy, kK1, kK2, kP1, kP2, kK3, kEx, kEy };

// Median of |r| for a 2-D isotropic Gaussian (Rayleigh) is sigma * sqrt(2 ln 2): the per-axis sigma from the
// median residual norm, insensitive to the outliers it is used to find.
constexpr double kRayleighMedianPerSigma = 1.1774100225154747;

// Solver tolerances: tight enough that noise-free synthetic data comes back to ~1e-9 relative (Ceres' defaults stop
// at 1e-6 relative cost change); the problems are small, so the extra iterations cost milliseconds.
constexpr double kFunctionTolerance = 1e-15;
constexpr double kGradientTolerance = 1e-15;
constexpr double kParameterTolerance = 1e-14;

struct Parameters {
  std::array<double, kNumIntrinsics> intrinsics{};
  std::array<double, kNumDistortion> dist{};
  std::array<double, kNumCentre> centre{};
  std::vector<std::array<double, kNumPose>> poses;  // one per used view
  std::array<double, kNumWarp> warp{};                // sag_x, sag_y mm (held at 0 unless fitted)
  BoardWarp warp_geometry;
};

// A view that takes part in the fit, with the inlier flag of each of its corners.
struct UsedView {
  int index = 0;
  const ViewObservations* view = nullptr;
  std::vector<bool> inlier;
};

using FreeMask = std::array<bool, kNumCameraParameters>;

FreeMask ComputeFreeMask(const CalibrationOptions& o, bool single_view) {
  FreeMask free;
  free.fill(true);
  for (int i = 0; i < kNumCameraParameters; ++i) {
    if (o.fixed.count(std::string(kParameterNames[i]))) free[i] = false;
  }
  if (o.model == DistortionModelKind::kSeidel) free[kK2] = free[kP1] = free[kP2] = free[kK3] = false;
  if (!o.fit_distortion_centre) free[kEx] = free[kEy] = false;
  if (single_view) free[kFx] = free[kFy] = free[kCx] = free[kCy] = false;
  return free;
}

CalibrationResult Failure(CalibrationStatus status, std::string message) {
  CalibrationResult r;
  r.status = status;
  r.message = std::move(message);
  return r;
}

// The intrinsics (fx, fy, cx, cy) with fx / fy held at `ratio`: x + B delta for a constant basis B whose first
// column moves fx and fy together (d fy = d fx / ratio) and whose other columns are the free ones of cx, cy. Written
// here because Ceres' stock manifolds hold entries fixed or keep norms, none ties two entries linearly.
class FixedAspectManifold final : public ceres::Manifold {
 public:
  FixedAspectManifold(double ratio, bool cx_free, bool cy_free) {
    basis_.push_back({1.0, 1.0 / ratio, 0.0, 0.0});
    if (cx_free) basis_.push_back({0.0, 0.0, 1.0, 0.0});
    if (cy_free) basis_.push_back({0.0, 0.0, 0.0, 1.0});
  }
  int AmbientSize() const override { return kNumIntrinsics; }
  int TangentSize() const override { return static_cast<int>(basis_.size()); }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    for (int i = 0; i < kNumIntrinsics; ++i) x_plus_delta[i] = x[i];
    for (size_t t = 0; t < basis_.size(); ++t) {
      for (int i = 0; i < kNumIntrinsics; ++i) x_plus_delta[i] += basis_[t][static_cast<size_t>(i)] * delta[t];
    }
    return true;
  }
  bool PlusJacobian(const double* /*x*/, double* jacobian) const override {
    const int m = TangentSize();
    for (int i = 0; i < kNumIntrinsics; ++i) {
      for (int t = 0; t < m; ++t) jacobian[i * m + t] = basis_[static_cast<size_t>(t)][static_cast<size_t>(i)];
    }
    return true;
  }
  // The columns have disjoint supports, so the least-squares tangent of y - x is each column's projection.
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    for (size_t t = 0; t < basis_.size(); ++t) {
      double dot = 0, norm2 = 0;
      for (int i = 0; i < kNumIntrinsics; ++i) {
        dot += basis_[t][static_cast<size_t>(i)] * (y[i] - x[i]);
        norm2 += basis_[t][static_cast<size_t>(i)] * basis_[t][static_cast<size_t>(i)];
      }
      y_minus_x[t] = dot / norm2;
    }
    return true;
  }
  bool MinusJacobian(const double* /*x*/, double* jacobian) const override {
    const int m = TangentSize();
    for (int t = 0; t < m; ++t) {
      double norm2 = 0;
      for (double b : basis_[static_cast<size_t>(t)]) norm2 += b * b;
      for (int i = 0; i < kNumIntrinsics; ++i) jacobian[t * kNumIntrinsics + i] = basis_[static_cast<size_t>(t)][static_cast<size_t>(i)] / norm2;
    }
    return true;
  }

 private:
  std::vector<std::array<double, kNumIntrinsics>> basis_;
};

// Adds a block to the problem holding the entries whose mask is false fixed (whole block constant if all are).
void AddBlock(ceres::Problem& problem, double* block, int size, const bool* free) {
  problem.AddParameterBlock(block, size);
  std::vector<int> fixed;
  for (int i = 0; i < size; ++i) {
    if (!free[i]) fixed.push_back(i);
  }
  if (static_cast<int>(fixed.size()) == size) {
    problem.SetParameterBlockConstant(block);
  } else if (!fixed.empty()) {
    problem.SetManifold(block, new ceres::SubsetManifold(size, fixed));
  }
}

ceres::LossFunction* MakeLoss(const CalibrationOptions& o) {
  switch (o.loss) {
    case RobustLoss::kHuber: return new ceres::HuberLoss(o.loss_scale_px);
    case RobustLoss::kCauchy: return new ceres::CauchyLoss(o.loss_scale_px);
    case RobustLoss::kNone: break;
  }
  return nullptr;
}

void BuildProblem(ceres::Problem& problem, Parameters& p, const std::vector<UsedView>& views, const FreeMask& free,
                  const CalibrationOptions& o) {
  if (o.fixed_aspect_ratio > 0 && free[kFx] && free[kFy]) {
    problem.AddParameterBlock(p.intrinsics.data(), kNumIntrinsics,
                              new FixedAspectManifold(o.fixed_aspect_ratio, free[kCx], free[kCy]));
  } else {
    AddBlock(problem, p.intrinsics.data(), kNumIntrinsics, &free[kFx]);
  }
  AddBlock(problem, p.dist.data(), kNumDistortion, &free[kK1]);
  AddBlock(problem, p.centre.data(), kNumCentre, &free[kEx]);
  problem.AddParameterBlock(p.warp.data(), kNumWarp);
  if (!o.fit_board_warp) problem.SetParameterBlockConstant(p.warp.data());
  for (size_t v = 0; v < views.size(); ++v) {
    problem.AddParameterBlock(p.poses[v].data(), kNumPose);
    const auto& corners = views[v].view->corners;
    for (size_t c = 0; c < corners.size(); ++c) {
      if (!views[v].inlier[c]) continue;
      problem.AddResidualBlock(
          ReprojectionCost::Create(corners[c].image_px, corners[c].target_mm, p.warp_geometry), MakeLoss(o),
          p.intrinsics.data(), p.dist.data(), p.centre.data(), p.poses[v].data(), p.warp.data());
    }
  }
}

std::optional<Eigen::Vector2d> Residual(const Parameters& p, const std::array<double, kNumPose>& pose,
                                        const CornerObservation& corner) {
  const ReprojectionCost cost(corner.image_px, corner.target_mm, p.warp_geometry);
  Eigen::Vector2d r;
  if (!cost(p.intrinsics.data(), p.dist.data(), p.centre.data(), pose.data(), p.warp.data(), r.data()) ||
      !r.allFinite()) {
    return std::nullopt;
  }
  return r;
}

bool AllFinite(const Parameters& p) {
  const auto finite = [](const auto& a) {
    return std::all_of(a.begin(), a.end(), [](double x) { return std::isfinite(x); });
  };
  return finite(p.intrinsics) && finite(p.dist) && finite(p.centre) && finite(p.warp) &&
         std::all_of(p.poses.begin(), p.poses.end(), finite);
}

// Degrees of freedom: a fixed aspect ratio makes fx and fy one.
int CountFree(const FreeMask& free, size_t views, const CalibrationOptions& o) {
  const int tied = o.fixed_aspect_ratio > 0 && free[kFx] && free[kFy] ? 1 : 0;
  return static_cast<int>(std::count(free.begin(), free.end(), true)) - tied + kNumPose * static_cast<int>(views);
}

// Solves, optionally rejecting outliers, then fills the statistics and the covariance of `result`.
CalibrationResult SolveAndReport(Parameters& p, std::vector<UsedView>& views, const FreeMask& free,
                                 const CalibrationOptions& o, CalibrationResult result) {
  const int free_parameters = CountFree(free, views.size(), o) + (o.fit_board_warp ? kNumWarp : 0);
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_SCHUR;
  solver_options.max_num_iterations = o.max_iterations;
  solver_options.function_tolerance = kFunctionTolerance;
  solver_options.gradient_tolerance = kGradientTolerance;
  solver_options.parameter_tolerance = kParameterTolerance;
  solver_options.num_threads = 1;

  for (int round = 0;; ++round) {
    int inliers = 0;
    for (const auto& v : views) inliers += static_cast<int>(std::count(v.inlier.begin(), v.inlier.end(), true));
    if (2 * inliers <= free_parameters) {
      return Failure(CalibrationStatus::kTooFewCorners,
                     fmt::format("{} corners give {} residuals for {} free parameters", inliers, 2 * inliers,
                                 free_parameters));
    }
    ceres::Problem problem;
    BuildProblem(problem, p, views, free, o);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    if (round == 0) result.solver.initial_cost = summary.initial_cost;
    result.solver.iterations += static_cast<int>(summary.iterations.size()) - 1;
    result.solver.final_cost = summary.final_cost;
    result.solver.converged = summary.termination_type == ceres::CONVERGENCE;
    result.solver.message = summary.message;
    result.outlier_rounds = round;
    if (!result.solver.converged || !std::isfinite(summary.final_cost) || !AllFinite(p)) {
      return Failure(CalibrationStatus::kSolverFailed,
                     fmt::format("the solver did not converge after {} iterations: {}", result.solver.iterations,
                                 summary.message));
    }
    if (!o.reject_outliers || round >= o.max_outlier_rounds) break;

    std::vector<double> norms;
    for (size_t v = 0; v < views.size(); ++v) {
      for (size_t c = 0; c < views[v].inlier.size(); ++c) {
        if (!views[v].inlier[c]) continue;
        const auto r = Residual(p, p.poses[v], views[v].view->corners[c]);
        norms.push_back(r ? r->norm() : INFINITY);
      }
    }
    std::nth_element(norms.begin(), norms.begin() + norms.size() / 2, norms.end());
    const double sigma_px = norms[norms.size() / 2] / kRayleighMedianPerSigma;
    const double threshold_px = o.outlier_threshold * sigma_px;
    int dropped = 0;
    for (size_t v = 0; v < views.size(); ++v) {
      for (size_t c = 0; c < views[v].inlier.size(); ++c) {
        if (!views[v].inlier[c]) continue;
        const auto r = Residual(p, p.poses[v], views[v].view->corners[c]);
        if (!r || r->norm() > threshold_px) {
          views[v].inlier[c] = false;
          ++dropped;
        }
      }
    }
    if (dropped == 0) break;
    // A pose needs at least 4 corners of its view; rejection must not leave one undetermined.
    for (const auto& v : views) {
      const auto left = std::count(v.inlier.begin(), v.inlier.end(), true);
      if (left < 4) {
        return Failure(CalibrationStatus::kTooFewCorners,
                       fmt::format("view {}: {} corners left after outlier rejection", v.index, left));
      }
    }
  }

  // Statistics on the inliers, residuals of every corner.
  double ssr = 0;
  int inliers = 0;
  for (size_t v = 0; v < views.size(); ++v) {
    double view_ssr = 0;
    int view_n = 0;
    const auto& corners = views[v].view->corners;
    for (size_t c = 0; c < corners.size(); ++c) {
      CornerResidual cr;
      cr.view = views[v].index;
      cr.corner_id = corners[c].id;
      cr.observed_px = corners[c].image_px;
      cr.outlier = !views[v].inlier[c];
      const auto r = Residual(p, p.poses[v], corners[c]);
      if (!r) {
        return Failure(CalibrationStatus::kSolverFailed,
                       fmt::format("view {}: corner {} lies behind the fitted camera", views[v].index, corners[c].id));
      }
      cr.residual_px = *r;
      if (cr.outlier) {
        result.outliers.push_back(cr);
      } else {
        view_ssr += r->squaredNorm();
        ++view_n;
      }
      result.residuals.push_back(cr);
    }
    ssr += view_ssr;
    inliers += view_n;
    result.per_view_rms_px.push_back(view_n > 0 ? std::sqrt(view_ssr / view_n) : 0.0);
  }
  result.corners_used = inliers;
  result.rms_px = std::sqrt(ssr / inliers);
  result.free_parameters = free_parameters;
  result.residual_variance_px2 = ssr / (2 * inliers - free_parameters);

  // Covariance of the camera parameters at the solution (the poses take part in J but are not reported). Every
  // pair of reported parameters, cross terms included: the covariance is what carries the calibration's uncertainty
  // to the clinic (pipeline/uncertainty.h), and k1, k2, k3 are strongly correlated.
  ceres::Problem problem;
  BuildProblem(problem, p, views, free, o);
  std::array<double, kNumCameraParameters> stddev{};
  struct Reported {
    double* block;
    int first;  // index of its first component in kParameterNames
    int size;
  };
  const Reported reported[] = {
      {p.intrinsics.data(), kFx, kNumIntrinsics}, {p.dist.data(), kK1, kNumDistortion}, {p.centre.data(), kEx, kNumCentre}};
  std::vector<double*> blocks;
  std::vector<const Reported*> reported_blocks;
  int next_row = 0;
  for (const auto& r : reported) {
    if (problem.IsParameterBlockConstant(r.block)) continue;
    blocks.push_back(r.block);
    reported_blocks.push_back(&r);
    next_row += problem.ParameterBlockTangentSize(r.block);
  }
  const int camera_rows = next_row;
  int warp_row = -1;
  if (o.fit_board_warp) {
    blocks.push_back(p.warp.data());
    warp_row = next_row;
    next_row += kNumWarp;
  }
  for (auto& pose : p.poses) blocks.push_back(pose.data());
  const TangentCovarianceResult covariance = TangentCovariance(problem, blocks);
  if (!covariance.ok) {
    // The reason is kept (it was dropped: a Jacobian that could not be evaluated read as rank deficiency).
    return Failure(CalibrationStatus::kCovarianceFailed,
                   fmt::format("the covariance at the solution failed ({}): fix the undetermined parameter or add "
                               "views",
                               covariance.message));
  }
  // From tangent to parameter coordinates: cov = P C P^T with P each block's plus-Jacobian (a selection of the free
  // entries, or fx and fy moving together under a fixed aspect ratio). Parameters held fixed have zero rows.
  Eigen::MatrixXd plus_jacobian = Eigen::MatrixXd::Zero(kNumCameraParameters, camera_rows);
  for (size_t b = 0; b < reported_blocks.size(); ++b) {
    const Reported& r = *reported_blocks[b];
    const int tangent = covariance.tangent_size[b];
    const ceres::Manifold* manifold = problem.GetManifold(r.block);
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jacobian(r.size, tangent);
    if (manifold == nullptr) {
      jacobian.setIdentity();
    } else if (!manifold->PlusJacobian(r.block, jacobian.data())) {
      return Failure(CalibrationStatus::kCovarianceFailed, "internal: a parameter block's Jacobian failed");
    }
    plus_jacobian.block(r.first, covariance.offset[b], r.size, tangent) = jacobian;
  }
  result.covariance = plus_jacobian * covariance.matrix.topLeftCorner(camera_rows, camera_rows) *
                      plus_jacobian.transpose() * result.residual_variance_px2;
  for (int i = 0; i < kNumCameraParameters; ++i) {
    const double var = result.covariance(i, i);
    stddev[static_cast<size_t>(i)] = free[static_cast<size_t>(i)] && var > 0 ? std::sqrt(var) : 0.0;
  }
  if (!result.covariance.allFinite()) {
    return Failure(CalibrationStatus::kCovarianceFailed, "non-finite parameter covariance");
  }

  const std::array<double, kNumCameraParameters> values = {
      p.intrinsics[0], p.intrinsics[1], p.intrinsics[2], p.intrinsics[3], p.dist[0], p.dist[1],
      p.dist[2],       p.dist[3],       p.dist[4],       p.centre[0],     p.centre[1]};
  for (int i = 0; i < kNumCameraParameters; ++i) {
    if (!std::isfinite(stddev[static_cast<size_t>(i)])) {
      return Failure(CalibrationStatus::kCovarianceFailed, "non-finite parameter covariance");
    }
    result.parameters.push_back({std::string(kParameterNames[i]), values[static_cast<size_t>(i)],
                                 stddev[static_cast<size_t>(i)], !free[static_cast<size_t>(i)]});
  }
  if (o.fit_board_warp) {
    const auto& warp_cov = covariance.matrix;
    BoardWarpEstimate w;
    w.sag_x_mm = p.warp[0];
    w.sag_y_mm = p.warp[1];
    w.sag_x_stddev_mm = std::sqrt(std::max(0.0, warp_cov(warp_row, warp_row) * result.residual_variance_px2));
    w.sag_y_stddev_mm = std::sqrt(std::max(0.0, warp_cov(warp_row + 1, warp_row + 1) * result.residual_variance_px2));
    w.centre_mm = p.warp_geometry.centre_mm;
    w.half_size_mm = p.warp_geometry.half_size_mm;
    result.board_warp = w;
  }
  auto& cam = result.camera;
  cam.fx_px = p.intrinsics[0];
  cam.fy_px = p.intrinsics[1];
  cam.cx_px = p.intrinsics[2];
  cam.cy_px = p.intrinsics[3];
  std::copy(p.dist.begin(), p.dist.end(), cam.dist.begin());
  cam.distortion_centre = {p.centre[0], p.centre[1]};
  for (size_t v = 0; v < views.size(); ++v) {
    ViewPose pose;
    pose.angle_axis = {p.poses[v][0], p.poses[v][1], p.poses[v][2]};
    pose.translation_mm = {p.poses[v][3], p.poses[v][4], p.poses[v][5]};
    result.cam_from_target.push_back(pose);
  }

  if (o.fixed_aspect_ratio > 0 && free[kFx] && free[kFy]) result.fixed_aspect_ratio = o.fixed_aspect_ratio;
  result.pixel_pitch_um = o.pixel_pitch_um;
  if (o.focal_mm > 0 && (!free[kFx] || o.pixel_pitch_um <= 0)) {
    result.focal_mm = o.focal_mm;
  } else if (o.pixel_pitch_um > 0) {
    result.focal_mm = 0.5 * (cam.fx_px + cam.fy_px) * o.pixel_pitch_um * 1e-3;
  }
  // Seidel sigma where the focal length in mm is known (paper Eq. 18; k1 = sigma f^2 / M_T^3).
  if (o.model == DistortionModelKind::kSeidel && result.focal_mm > 0) {
    SeidelEstimate s;
    s.magnification = o.magnification;
    s.pixel_pitch_um = o.pixel_pitch_um;
    // With the pitch known, the fitted focal length in mm is the one the normalised k1 refers to.
    s.focal_mm = result.focal_mm;
    s.sigma_per_mm2 = model::BrownK1ToSeidelSigma(cam.dist[0], s.magnification, s.focal_mm);
    s.sigma_stddev_per_mm2 = std::abs(model::BrownK1ToSeidelSigma(stddev[kK1], s.magnification, s.focal_mm));
    result.seidel = s;
  }
  result.status = CalibrationStatus::kOk;
  result.message = fmt::format("rms {:.4f} px over {} corners in {} views, {} outliers", result.rms_px, inliers,
                               views.size(), result.outliers.size());
  return result;
}

// Checks that the target points are planar (z = 0) and span two dimensions.
std::string CheckTargetLayout(const ViewObservations& view) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& c : view.corners) {
    if (std::abs(c.target_mm.z()) > 0) return fmt::format("corner {} is off the target plane (z = {} mm)", c.id, c.target_mm.z());
    mean += c.target_mm.head<2>();
  }
  mean /= static_cast<double>(view.corners.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& c : view.corners) {
    const Eigen::Vector2d d = c.target_mm.head<2>() - mean;
    scatter += d * d.transpose();
  }
  const Eigen::Vector2d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(scatter).eigenvalues();
  // Collinear corners leave the second eigenvalue at rounding level relative to the first.
  if (!(ev(0) > 1e-9 * ev(1))) return "the corners are collinear";
  return {};
}

std::array<double, kNumPose> ToArray(const ViewPose& pose) {
  return {pose.angle_axis.x(),     pose.angle_axis.y(),     pose.angle_axis.z(),
          pose.translation_mm.x(), pose.translation_mm.y(), pose.translation_mm.z()};
}

}  // namespace

std::string_view ToString(DistortionModelKind model) noexcept {
  return model == DistortionModelKind::kSeidel ? "seidel" : "brown5";
}

std::optional<DistortionModelKind> ParseDistortionModel(std::string_view name) noexcept {
  if (name == "seidel") return DistortionModelKind::kSeidel;
  if (name == "brown5") return DistortionModelKind::kBrown5;
  return std::nullopt;
}

std::string_view ToString(RobustLoss loss) noexcept {
  switch (loss) {
    case RobustLoss::kHuber: return "huber";
    case RobustLoss::kCauchy: return "cauchy";
    case RobustLoss::kNone: break;
  }
  return "none";
}

std::optional<RobustLoss> ParseRobustLoss(std::string_view name) noexcept {
  if (name == "none") return RobustLoss::kNone;
  if (name == "huber") return RobustLoss::kHuber;
  if (name == "cauchy") return RobustLoss::kCauchy;
  return std::nullopt;
}

std::string_view ToString(CalibrationStatus status) noexcept {
  switch (status) {
    case CalibrationStatus::kOk: return "ok";
    case CalibrationStatus::kInvalidOptions: return "invalid options";
    case CalibrationStatus::kInvalidInput: return "invalid input";
    case CalibrationStatus::kTooFewViews: return "too few views";
    case CalibrationStatus::kTooFewCorners: return "too few corners";
    case CalibrationStatus::kDegenerate: return "degenerate";
    case CalibrationStatus::kSolverFailed: return "solver failed";
    case CalibrationStatus::kCovarianceFailed: return "covariance failed";
  }
  return "unknown";
}

bool CalibrationOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string reason) {
    if (why) *why = std::move(reason);
    return false;
  };
  for (const auto& name : fixed) {
    if (std::find(std::begin(kParameterNames), std::end(kParameterNames), name) == std::end(kParameterNames)) {
      return fail(fmt::format("unknown parameter '{}' to fix (one of fx, fy, cx, cy, k1, k2, p1, p2, k3, ex, ey)", name));
    }
  }
  if (fit_distortion_centre && model == DistortionModelKind::kBrown5 && !(fixed.count("p1") && fixed.count("p2"))) {
    return fail("a free distortion centre and free p1, p2 are the same distortion to second order: fix p1,p2 or "
                "the centre");
  }
  if (!std::isfinite(fixed_aspect_ratio) || fixed_aspect_ratio < 0 ||
      (fixed_aspect_ratio > 0 && (fixed_aspect_ratio < 0.5 || fixed_aspect_ratio > 2))) {
    return fail(fmt::format("fixed aspect ratio fx / fy = {} is not a camera's (0 = free, else within [0.5, 2])",
                            fixed_aspect_ratio));
  }
  if (fixed_aspect_ratio > 0 && (fixed.count("fx") || fixed.count("fy"))) {
    return fail("a fixed aspect ratio ties fx and fy: fix neither, or fix both without the ratio");
  }
  if (!(loss_scale_px > 0)) return fail("loss scale must be > 0 px");
  if (!(outlier_threshold > 1)) return fail("outlier threshold must be > 1 robust sigma");
  if (max_outlier_rounds < 0) return fail("max outlier rounds must be >= 0");
  if (min_views < 2) return fail("min views must be >= 2");
  if (min_corners_per_view < 4) return fail("min corners per view must be >= 4");
  if (max_iterations < 1) return fail("max iterations must be >= 1");
  // Finite, and finite in pixels too: --focal-mm inf (or a pitch of 1e-300 um) reached Ceres as an Inf parameter.
  if (!(std::isfinite(focal_mm) && std::isfinite(pixel_pitch_um) && std::isfinite(distance_mm)) || focal_mm < 0 ||
      pixel_pitch_um < 0 || distance_mm < 0) {
    return fail("focal, pitch and distance must be finite and >= 0");
  }
  if (focal_mm > 0 && pixel_pitch_um > 0 && !std::isfinite(focal_mm / (pixel_pitch_um * 1e-3))) {
    return fail("focal / pixel pitch is not a finite focal length in pixels");
  }
  if (!(magnification != 0) || !std::isfinite(magnification)) return fail("magnification M_T must be non-zero");
  return true;
}

CalibrationResult CalibrateMultiView(const std::vector<ViewObservations>& views, const CalibrationOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Failure(CalibrationStatus::kInvalidOptions, why);
  CalibrationResult result;
  result.model = options.model;
  std::vector<ViewObservations> usable;
  std::vector<int> usable_index;
  for (size_t i = 0; i < views.size(); ++i) {
    const auto& v = views[i];
    const int idx = static_cast<int>(i);
    if (static_cast<int>(v.corners.size()) < options.min_corners_per_view) {
      result.skipped_views.push_back(
          {idx, fmt::format("{} corners, fewer than {}", v.corners.size(), options.min_corners_per_view)});
      continue;
    }
    if (const auto layout = CheckTargetLayout(v); !layout.empty()) {
      if (layout.find("off the target plane") != std::string::npos) {
        return Failure(CalibrationStatus::kInvalidInput, fmt::format("view {} ({}): {}", i, v.image_path, layout));
      }
      result.skipped_views.push_back({idx, layout});
      continue;
    }
    if (!usable.empty() && (v.image_width != usable.front().image_width || v.image_height != usable.front().image_height)) {
      return Failure(CalibrationStatus::kInvalidInput,
                     fmt::format("view {} ({}) is {}x{} px, the first is {}x{} px", i, v.image_path, v.image_width,
                                 v.image_height, usable.front().image_width, usable.front().image_height));
    }
    usable.push_back(v);
    usable_index.push_back(idx);
  }
  if (static_cast<int>(usable.size()) < options.min_views) {
    auto f = Failure(CalibrationStatus::kTooFewViews,
                     fmt::format("{} usable views, at least {} needed", usable.size(), options.min_views));
    f.skipped_views = result.skipped_views;
    return f;
  }
  const ZhangInitialisation init = InitialiseZhang(usable);
  if (!init.ok) return Failure(CalibrationStatus::kDegenerate, init.message);

  Parameters p;
  p.intrinsics = {init.fx_px, init.fy_px, init.cx_px, init.cy_px};
  if (options.fixed_aspect_ratio > 0) {
    // Start on the constraint with Zhang's geometric-mean focal length.
    const double f = std::sqrt(init.fx_px * init.fy_px);
    p.intrinsics[0] = f * std::sqrt(options.fixed_aspect_ratio);
    p.intrinsics[1] = f / std::sqrt(options.fixed_aspect_ratio);
  }
  if (options.fit_board_warp) {
    // The warp's frame: the bounding box of every corner seen (the printed pattern as far as the views know it).
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(INFINITY), hi = Eigen::Vector2d::Constant(-INFINITY);
    for (const auto& v : usable) {
      for (const auto& c : v.corners) {
        lo = lo.cwiseMin(c.target_mm.head<2>());
        hi = hi.cwiseMax(c.target_mm.head<2>());
      }
    }
    p.warp_geometry.centre_mm = 0.5 * (lo + hi);
    p.warp_geometry.half_size_mm = 0.5 * (hi - lo);
  }
  for (const auto& pose : init.cam_from_target) p.poses.push_back(ToArray(pose));
  // Refine each pose for the initial K (Zhang's rotation projection is only least-squares in the algebraic sense).
  const cv::Matx33d k(p.intrinsics[0], 0, p.intrinsics[2], 0, p.intrinsics[1], p.intrinsics[3], 0, 0, 1);
  for (size_t v = 0; v < usable.size(); ++v) {
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const auto& c : usable[v].corners) {
      object.emplace_back(c.target_mm.x(), c.target_mm.y(), 0.0);
      image.emplace_back(c.image_px.x(), c.image_px.y());
    }
    cv::Vec3d rvec(p.poses[v][0], p.poses[v][1], p.poses[v][2]), tvec(p.poses[v][3], p.poses[v][4], p.poses[v][5]);
    if (cv::solvePnP(object, image, k, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE) && tvec[2] > 0) {
      p.poses[v] = {rvec[0], rvec[1], rvec[2], tvec[0], tvec[1], tvec[2]};
    }
  }

  std::vector<UsedView> used;
  for (size_t v = 0; v < usable.size(); ++v) {
    used.push_back({usable_index[v], &usable[v], std::vector<bool>(usable[v].corners.size(), true)});
  }
  result.single_view = false;
  result.camera.width_px = usable.front().image_width;
  result.camera.height_px = usable.front().image_height;
  result.views_used = usable_index;
  auto skipped = result.skipped_views;
  auto out = SolveAndReport(p, used, ComputeFreeMask(options, false), options, std::move(result));
  if (!out.ok()) out.skipped_views = skipped;
  out.model = options.model;
  return out;
}

CalibrationResult CalibrateSingleView(const ViewObservations& view, const CalibrationOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Failure(CalibrationStatus::kInvalidOptions, why);
  if (options.fit_board_warp) {
    return Failure(CalibrationStatus::kInvalidOptions,
                   "a board warp needs several views (one view cannot tell a warp from distortion)");
  }
  if (options.fixed_aspect_ratio > 0) {
    return Failure(CalibrationStatus::kInvalidOptions,
                   "a fixed aspect ratio applies to multi-view fits (a single view holds fx = fy from the focal "
                   "distance and the pixel pitch)");
  }
  if (!(options.focal_mm > 0 && options.pixel_pitch_um > 0 && options.distance_mm > 0)) {
    return Failure(CalibrationStatus::kInvalidOptions,
                   "single-view calibration needs the focal distance (mm), the pixel pitch (um) and the nominal "
                   "target distance (mm)");
  }
  if (view.image_width <= 0 || view.image_height <= 0) {
    return Failure(CalibrationStatus::kInvalidInput, fmt::format("{}: image size unknown", view.image_path));
  }
  if (static_cast<int>(view.corners.size()) < options.min_corners_per_view) {
    return Failure(CalibrationStatus::kTooFewCorners,
                   fmt::format("{}: {} corners, fewer than {}", view.image_path, view.corners.size(),
                               options.min_corners_per_view));
  }
  if (const auto layout = CheckTargetLayout(view); !layout.empty()) {
    return Failure(CalibrationStatus::kDegenerate, fmt::format("{}: {}", view.image_path, layout));
  }
  Parameters p;
  const double f_px = options.focal_mm / (options.pixel_pitch_um * 1e-3);
  p.intrinsics = {f_px, f_px, 0.5 * (view.image_width - 1), 0.5 * (view.image_height - 1)};

  // Pose: planar PnP (IPPE) with zero distortion, and an iterative PnP started fronto-parallel at the nominal
  // distance with the target centroid on the axis; the one with the smaller reprojection error wins.
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& c : view.corners) {
    object.emplace_back(c.target_mm.x(), c.target_mm.y(), 0.0);
    image.emplace_back(c.image_px.x(), c.image_px.y());
    centroid += c.target_mm;
  }
  centroid /= static_cast<double>(view.corners.size());
  const cv::Matx33d k(f_px, 0, p.intrinsics[2], 0, f_px, p.intrinsics[3], 0, 0, 1);
  const auto reprojection = [&](const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
    std::vector<cv::Point2d> projected;
    cv::projectPoints(object, rvec, tvec, k, cv::noArray(), projected);
    double ssr = 0;
    for (size_t i = 0; i < projected.size(); ++i) {
      const cv::Point2d d = projected[i] - image[i];
      ssr += d.dot(d);
    }
    return std::isfinite(ssr) && tvec[2] > 0 ? ssr : INFINITY;
  };
  cv::Vec3d best_r(0, 0, 0), best_t(-centroid.x(), -centroid.y(), options.distance_mm);
  double best = reprojection(best_r, best_t);
  {
    cv::Vec3d r = best_r, t = best_t;
    if (cv::solvePnP(object, image, k, cv::noArray(), r, t, true, cv::SOLVEPNP_ITERATIVE) && reprojection(r, t) < best) {
      best = reprojection(r, t);
      best_r = r;
      best_t = t;
    }
    if (cv::solvePnP(object, image, k, cv::noArray(), r, t, false, cv::SOLVEPNP_IPPE) && reprojection(r, t) < best) {
      best = reprojection(r, t);
      best_r = r;
      best_t = t;
    }
  }
  p.poses.push_back({best_r[0], best_r[1], best_r[2], best_t[0], best_t[1], best_t[2]});

  std::vector<UsedView> used{{0, &view, std::vector<bool>(view.corners.size(), true)}};
  CalibrationResult result;
  result.model = options.model;
  result.single_view = true;
  result.camera.width_px = view.image_width;
  result.camera.height_px = view.image_height;
  result.views_used = {0};
  auto out = SolveAndReport(p, used, ComputeFreeMask(options, true), options, std::move(result));
  out.model = options.model;
  out.single_view = true;
  return out;
}

}  // namespace topocal::calib
