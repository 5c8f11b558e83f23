#include "calib/calibrate_solve.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <ceres/ceres.h>
#include <fmt/format.h>

#include "calib/estimate_table.h"
#include "calib/jacobian_covariance.h"
#include "model/distortion.h"

namespace topocal::calib::internal {
namespace {

// Median of |r| for a 2-D isotropic Gaussian (Rayleigh) is sigma * sqrt(2 ln 2): the per-axis sigma from the
// median residual norm, insensitive to the outliers it is used to find.
constexpr double kRayleighMedianPerSigma = 1.1774100225154747;

// Solver tolerances: tight enough that noise-free synthetic data comes back to ~1e-9 relative (Ceres' defaults stop
// at 1e-6 relative cost change); the problems are small, so the extra iterations cost milliseconds.
constexpr double kFunctionTolerance = 1e-15;
constexpr double kGradientTolerance = 1e-15;
constexpr double kParameterTolerance = 1e-14;

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

// Adds a block to the problem holding the entries whose mask (from free[first]) is false fixed (whole block constant
// if all are).
void AddBlock(ceres::Problem& problem, double* block, int size, const FreeMask& free, int first) {
  problem.AddParameterBlock(block, size);
  std::vector<int> fixed;
  for (int i = 0; i < size; ++i) {
    if (!free[static_cast<size_t>(first + i)]) fixed.push_back(i);
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
    AddBlock(problem, p.intrinsics.data(), kNumIntrinsics, free, kFx);
  }
  AddBlock(problem, p.dist.data(), model::LensParameterCount(p.lens), free, kDist);
  AddBlock(problem, p.centre.data(), kNumCentre, free, CentreIndex(p.lens));
  problem.AddParameterBlock(p.warp.data(), kNumWarp);
  if (!o.fit_board_warp) problem.SetParameterBlockConstant(p.warp.data());
  for (size_t v = 0; v < views.size(); ++v) {
    problem.AddParameterBlock(p.poses[v].data(), kNumPose);
    const auto& corners = views[v].view->corners;
    for (size_t c = 0; c < corners.size(); ++c) {
      if (!views[v].inlier[c]) continue;
      ceres::CostFunction* cost = std::visit(
          [&](auto lens) {
            return ReprojectionCost<decltype(lens)>::Create(corners[c].image_px, corners[c].target_mm,
                                                           p.warp_geometry);
          },
          p.lens);
      problem.AddResidualBlock(cost, MakeLoss(o), p.intrinsics.data(), p.dist.data(), p.centre.data(),
                               p.poses[v].data(), p.warp.data());
    }
  }
}

std::optional<Eigen::Vector2d> Residual(const Parameters& p, const std::array<double, kNumPose>& pose,
                                        const CornerObservation& corner) {
  Eigen::Vector2d r;
  const bool ok = std::visit(
      [&](auto lens) {
        const ReprojectionCost<decltype(lens)> cost(corner.image_px, corner.target_mm, p.warp_geometry);
        return cost(p.intrinsics.data(), p.dist.data(), p.centre.data(), pose.data(), p.warp.data(), r.data());
      },
      p.lens);
  if (!ok || !r.allFinite()) {
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

ceres::Solver::Options SolverOptions(const CalibrationOptions& o) {
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_SCHUR;
  solver_options.max_num_iterations = o.max_iterations;
  solver_options.function_tolerance = kFunctionTolerance;
  solver_options.gradient_tolerance = kGradientTolerance;
  solver_options.parameter_tolerance = kParameterTolerance;
  solver_options.num_threads = 1;
  return solver_options;
}

// One round of outlier rejection: the inliers whose residual is above outlier_threshold robust sigmas (from the
// median residual norm) become outliers. Returns how many.
int RejectOutliers(const Parameters& p, std::vector<UsedView>& views, const CalibrationOptions& o) {
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
  return dropped;
}

// Solves, then (when asked) rejects outliers and solves again until none is dropped or the rounds run out; the
// solver's figures into result. False with the failure in result.
bool SolveRejectingOutliers(Parameters& p, std::vector<UsedView>& views, const FreeMask& free,
                            const CalibrationOptions& o, int free_parameters, CalibrationResult* result) {
  const ceres::Solver::Options solver_options = SolverOptions(o);
  for (int round = 0;; ++round) {
    int inliers = 0;
    for (const auto& v : views) inliers += static_cast<int>(std::count(v.inlier.begin(), v.inlier.end(), true));
    if (2 * inliers <= free_parameters) {
      *result = Failure(CalibrationStatus::kTooFewCorners,
                        fmt::format("{} corners give {} residuals for {} free parameters", inliers, 2 * inliers,
                                    free_parameters));
      return false;
    }
    ceres::Problem problem;
    BuildProblem(problem, p, views, free, o);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    if (round == 0) result->solver.initial_cost = summary.initial_cost;
    result->solver.iterations += static_cast<int>(summary.iterations.size()) - 1;
    result->solver.final_cost = summary.final_cost;
    result->solver.converged = summary.termination_type == ceres::CONVERGENCE;
    result->solver.message = summary.message;
    result->outlier_rounds = round;
    if (!result->solver.converged || !std::isfinite(summary.final_cost) || !AllFinite(p)) {
      // A fit that runs out of iterations usually crawls along parameters the views do not separate (a rational
      // model's numerator against its denominator): say what to do about it.
      *result = Failure(CalibrationStatus::kSolverFailed,
                        fmt::format("the solver did not converge after {} iterations: {} (hold fixed what the views "
                                    "cannot determine, or fit a model with fewer coefficients)",
                                    result->solver.iterations, summary.message));
      return false;
    }
    if (!o.reject_outliers || round >= o.max_outlier_rounds) break;
    if (RejectOutliers(p, views, o) == 0) break;
    // A pose needs at least 4 corners of its view; rejection must not leave one undetermined.
    for (const auto& v : views) {
      const auto left = std::count(v.inlier.begin(), v.inlier.end(), true);
      if (left < 4) {
        *result = Failure(CalibrationStatus::kTooFewCorners,
                          fmt::format("view {}: {} corners left after outlier rejection", v.index, left));
        return false;
      }
    }
  }
  return true;
}

// Statistics on the inliers, residuals of every corner. False with the failure in result.
bool FillResiduals(const Parameters& p, const std::vector<UsedView>& views, int free_parameters,
                   CalibrationResult* result) {
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
        *result = Failure(CalibrationStatus::kSolverFailed,
                          fmt::format("view {}: corner {} lies behind the fitted camera", views[v].index, corners[c].id));
        return false;
      }
      cr.residual_px = *r;
      if (cr.outlier) {
        result->outliers.push_back(cr);
      } else {
        view_ssr += r->squaredNorm();
        ++view_n;
      }
      result->residuals.push_back(cr);
    }
    ssr += view_ssr;
    inliers += view_n;
    result->per_view_rms_px.push_back(view_n > 0 ? std::sqrt(view_ssr / view_n) : 0.0);
  }
  result->corners_used = inliers;
  result->rms_px = std::sqrt(ssr / inliers);
  result->free_parameters = free_parameters;
  result->residual_variance_px2 = ssr / (2 * inliers - free_parameters);
  return true;
}

// The camera parameters the result reports, in CameraParameterNames order: fx, fy, cx, cy, the lens model's
// coefficients, ex, ey.
EstimateTable CameraTable(const Parameters& p, const DistortionModelKind& model) {
  const auto names = CameraParameterNames(model);
  EstimateTable table;
  const int centre = CentreIndex(p.lens);
  for (int i = 0; i < static_cast<int>(names.size()); ++i) {
    const std::string& name = names[static_cast<size_t>(i)];
    if (i < kDist) {
      table.Add(name, p.intrinsics.data(), i);
    } else if (i < centre) {
      table.Add(name, p.dist.data(), i - kDist);
    } else {
      table.Add(name, p.centre.data(), i - centre);
    }
  }
  return table;
}

// Covariance of the camera parameters at the solution into result (and the board warp's estimate), their standard
// deviations into stddev. False with the failure in result.
bool ComputeCovariance(Parameters& p, const FreeMask& free, const std::vector<UsedView>& views,
                       const CalibrationOptions& o, std::vector<double>* stddev, CalibrationResult* result) {
  // The poses take part in J but are not reported. Every pair of reported parameters, cross terms included: the
  // covariance is what carries the calibration's uncertainty to the clinic (pipeline/uncertainty.h), and k1, k2, k3
  // are strongly correlated.
  ceres::Problem problem;
  BuildProblem(problem, p, views, free, o);
  std::vector<double*> blocks;
  for (double* b : {p.intrinsics.data(), p.dist.data(), p.centre.data()}) {
    if (!problem.IsParameterBlockConstant(b)) blocks.push_back(b);
  }
  if (o.fit_board_warp) blocks.push_back(p.warp.data());
  for (auto& pose : p.poses) blocks.push_back(pose.data());
  const TangentCovarianceResult covariance = TangentCovariance(problem, blocks);
  if (!covariance.ok) {
    // The reason is kept (it was dropped: a Jacobian that could not be evaluated read as rank deficiency).
    *result = Failure(CalibrationStatus::kCovarianceFailed,
                      fmt::format("the covariance at the solution failed ({}): fix the undetermined parameter or add "
                                  "views",
                                  covariance.message));
    return false;
  }
  std::string why;
  const auto camera = CameraTable(p, result->model).Covariance(problem, blocks, covariance,
                                                               result->residual_variance_px2, &why);
  if (!camera) {
    *result = Failure(CalibrationStatus::kCovarianceFailed, why);
    return false;
  }
  result->covariance = *camera;
  *stddev = EstimateTable::StandardDeviations(result->covariance);  // a fixed parameter's row is zero: 0
  if (o.fit_board_warp) {
    EstimateTable warp;
    warp.AddBlock({"sag_x_mm", "sag_y_mm"}, p.warp.data());
    const auto warp_cov = warp.Covariance(problem, blocks, covariance, result->residual_variance_px2, &why);
    if (!warp_cov) {
      *result = Failure(CalibrationStatus::kCovarianceFailed, why);
      return false;
    }
    const auto sd = EstimateTable::StandardDeviations(*warp_cov);
    BoardWarpEstimate w;
    w.sag_x_mm = p.warp[0];
    w.sag_y_mm = p.warp[1];
    w.sag_x_stddev_mm = sd[0];
    w.sag_y_stddev_mm = sd[1];
    w.centre_mm = p.warp_geometry.centre_mm;
    w.half_size_mm = p.warp_geometry.half_size_mm;
    result->board_warp = w;
  }
  return true;
}

// The parameters with their standard deviations, the camera and the views' poses into result. False with the
// failure in result.
bool FillParameters(const Parameters& p, const FreeMask& free, const std::vector<double>& stddev,
                    const std::vector<UsedView>& views, CalibrationResult* result) {
  const EstimateTable table = CameraTable(p, result->model);
  const auto names = table.Names();
  const auto values = table.Values();
  for (size_t i = 0; i < names.size(); ++i) {
    if (!std::isfinite(stddev[i])) {
      *result = Failure(CalibrationStatus::kCovarianceFailed, "non-finite parameter covariance");
      return false;
    }
    result->parameters.push_back({names[i], values[i], stddev[i], !free[i]});
  }
  auto& cam = result->camera;
  cam.lens = p.lens;
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
    result->cam_from_target.push_back(pose);
  }
  return true;
}

// The focal length in mm (given, or from the fit and the pixel pitch) and the Seidel sigma where it is known.
void FillFocalAndSeidel(const FreeMask& free, const CalibrationOptions& o,
                        const std::vector<double>& stddev, CalibrationResult* result) {
  const auto& cam = result->camera;
  if (o.fixed_aspect_ratio > 0 && free[kFx] && free[kFy]) result->fixed_aspect_ratio = o.fixed_aspect_ratio;
  result->pixel_pitch_um = o.pixel_pitch_um;
  if (o.focal_mm > 0 && (!free[kFx] || o.pixel_pitch_um <= 0)) {
    result->focal_mm = o.focal_mm;
  } else if (o.pixel_pitch_um > 0) {
    result->focal_mm = 0.5 * (cam.fx_px + cam.fy_px) * o.pixel_pitch_um * 1e-3;
  }
  // Seidel sigma where the focal length in mm is known (paper Eq. 18; k1 = sigma f^2 / M_T^3).
  if (o.model.seidel && result->focal_mm > 0) {
    SeidelEstimate s;
    s.magnification = o.magnification;
    s.pixel_pitch_um = o.pixel_pitch_um;
    // With the pitch known, the fitted focal length in mm is the one the normalised k1 refers to.
    s.focal_mm = result->focal_mm;
    s.sigma_per_mm2 = model::BrownK1ToSeidelSigma(cam.dist[0], s.magnification, s.focal_mm);
    s.sigma_stddev_per_mm2 = std::abs(model::BrownK1ToSeidelSigma(stddev[kDist], s.magnification, s.focal_mm));
    result->seidel = s;
  }
}

}  // namespace

CalibrationResult SolveAndReport(Parameters& p, std::vector<UsedView>& views, const FreeMask& free,
                                 const CalibrationOptions& o, CalibrationResult result) {
  const int free_parameters = CountFree(free, views.size(), o) + (o.fit_board_warp ? kNumWarp : 0);
  if (!SolveRejectingOutliers(p, views, free, o, free_parameters, &result)) return result;
  if (!FillResiduals(p, views, free_parameters, &result)) return result;
  std::vector<double> stddev;
  if (!ComputeCovariance(p, free, views, o, &stddev, &result)) return result;
  if (!FillParameters(p, free, stddev, views, &result)) return result;
  FillFocalAndSeidel(free, o, stddev, &result);
  result.status = CalibrationStatus::kOk;
  result.message = fmt::format("rms {:.4f} px over {} corners in {} views, {} outliers", result.rms_px,
                               result.corners_used, views.size(), result.outliers.size());
  return result;
}

}  // namespace topocal::calib::internal
