#include "calib/device_fit.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>

#include <ceres/ceres.h>
#include <ceres/normal_prior.h>
#include <fmt/format.h>

#include "calib/jacobian_covariance.h"

namespace topocal::calib {
namespace {

// Minimum identified spots per ball image: below ~a ring's worth the ball's three coordinates and the device share
// too little; the paper's design images 624.
constexpr int kMinSpotsPerBall = 24;

// One spot of one ball image: predicted - observed pixel, divided by the spot noise.
template <int kDistortionParams>
struct BallSpotResidual {
  model::DeviceProjectionSetup setup;
  double radius_mm;
  double reference_radius_mm;
  Eigen::Vector3d designed_target_mm;
  Eigen::Vector2d designed_on_sphere_mm;
  Eigen::Vector2d observed_px;
  double inv_sigma_px;

  template <typename T>
  bool operator()(const T* pose, const T* radial_scale, const T* principal, const T* a, const T* distortion,
                  const T* ball, T* residual) const {
    const auto value = [](const T& v) -> double {
      if constexpr (std::is_same_v<T, double>) return v; else return v.a;
    };
    // Newton start: the reflection point on a ball of another radius has about the same normal as on the
    // reference sphere, so it sits at centre + (R / r_e) (designed point - reference centre) laterally.
    const Eigen::Vector2d initial = designed_on_sphere_mm * (radius_mm / reference_radius_mm) +
                                    Eigen::Vector2d(value(ball[0]), value(ball[1]));
    T px[2];
    if (!model::ProjectBallSpot(setup, pose, radial_scale, principal, a, distortion, ball, radius_mm,
                                designed_target_mm.data(), initial, px)) {
      return false;
    }
    residual[0] = (px[0] - observed_px.x()) * inv_sigma_px;
    residual[1] = (px[1] - observed_px.y()) * inv_sigma_px;
    return true;
  }
};

template <int N>
ceres::CostFunction* MakeSpotCost(const BallSpotResidual<N>& r) {
  return new ceres::AutoDiffCostFunction<BallSpotResidual<N>, 2, model::ScreenPose::kNumParams, 1, 2, 1, N, 3>(
      new BallSpotResidual<N>(r));
}

// A diagonal Gaussian prior: (x - mean) / sigma per component.
ceres::CostFunction* Prior(const Eigen::VectorXd& mean, const Eigen::VectorXd& sigma) {
  const Eigen::MatrixXd a = sigma.cwiseInverse().asDiagonal();
  return new ceres::NormalPrior(a, mean);
}

// The parameter blocks of the fit.
struct Blocks {
  std::array<double, model::ScreenPose::kNumParams> pose{};
  double radial_scale = 1;
  std::array<double, 2> principal{};
  double a = 0;
  std::vector<double> distortion;   // 1 (Seidel sigma) or 5 (Brown)
  std::vector<std::array<double, 3>> balls;
};

struct Observation {
  int ball;
  const model::TargetPoint* target;
  Eigen::Vector2d px;
};

}  // namespace

bool DeviceTolerances::IsValid(std::string* why) const {
  const std::pair<const char*, double> all[] = {
      {"tilt_deg", tilt_deg},       {"roll_deg", roll_deg},          {"lateral_mm", lateral_mm},
      {"axial_mm", axial_mm},       {"principal_point_mm", principal_point_mm},
      {"a_relative", a_relative},   {"radial_scale", radial_scale},  {"sigma_per_mm2", sigma_per_mm2},
      {"brown_k", brown_k},         {"ball_placement_mm", ball_placement_mm}};
  for (const auto& [name, v] : all) {
    if (!(v > 0) || !std::isfinite(v)) {
      if (why) *why = fmt::format("tolerance {} must be > 0 and finite (got {})", name, v);
      return false;
    }
  }
  return true;
}

bool DeviceFitOptions::IsValid(std::string* why) const {
  if (!priors.IsValid(why)) return false;
  if (!(spot_sigma_px > 0) || !std::isfinite(spot_sigma_px)) {
    if (why) *why = fmt::format("spot_sigma_px must be > 0 (got {})", spot_sigma_px);
    return false;
  }
  if (datum_ball < 0) {
    if (why) *why = "datum_ball must be >= 0";
    return false;
  }
  if (!std::isfinite(datum_z_mm) || std::abs(datum_z_mm) > 10) {
    if (why) *why = fmt::format("datum_z_mm must be within +-10 mm (got {})", datum_z_mm);
    return false;
  }
  if (!(max_chi2_per_dof > 0) || max_iterations < 1) {
    if (why) *why = "max_chi2_per_dof must be > 0 and max_iterations >= 1";
    return false;
  }
  return true;
}

model::DeviceCovariance DeviceFit::Covariance() const {
  model::DeviceCovariance c;
  for (const auto& p : parameters) c.names.push_back(p.name);
  c.matrix = covariance;
  return c;
}

std::optional<DeviceParameterEstimate> DeviceFit::Parameter(const std::string& name) const {
  for (const auto& p : parameters) {
    if (p.name == name) return p;
  }
  return std::nullopt;
}

DeviceFit FitDevice(const model::Device& nominal, const model::TopographerParams& design,
                    const std::vector<model::TargetPoint>& designed_targets, const std::vector<BallView>& balls,
                    const DeviceFitOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  DeviceFit fit;
  fit.device = nominal;
  const auto fail = [&fit](std::string m) {
    fit.ok = false;
    fit.message = std::move(m);
    return fit;
  };
  if (balls.empty()) return fail("no ball images");
  if (options.datum_ball >= static_cast<int>(balls.size())) {
    return fail(fmt::format("datum ball {} but only {} ball images", options.datum_ball + 1, balls.size()));
  }
  const bool brown = std::holds_alternative<model::BrownParams>(nominal.distortion);
  const model::DeviceProjectionSetup setup = model::ProjectionSetupOf(nominal, design);

  std::map<model::SpotId, const model::TargetPoint*> target_of;
  for (const auto& t : designed_targets) target_of[t.id] = &t;
  std::vector<Observation> observations;
  for (size_t b = 0; b < balls.size(); ++b) {
    const auto& ball = balls[b];
    if (!(ball.radius_mm > 0) || !std::isfinite(ball.radius_mm)) {
      return fail(fmt::format("{}: ball radius must be > 0 (got {})", ball.name, ball.radius_mm));
    }
    int used = 0;
    for (const auto& [id, px] : ball.spots_px) {
      const auto it = target_of.find(id);
      if (it == target_of.end() || !px.allFinite()) continue;
      observations.push_back({static_cast<int>(b), it->second, px});
      ++used;
    }
    if (used < kMinSpotsPerBall) {
      return fail(fmt::format("{}: {} identified spots, at least {} needed", ball.name, used, kMinSpotsPerBall));
    }
    fit.ball_spots.push_back(used);
  }

  Blocks blk;
  blk.pose = nominal.screen.AsArray();
  blk.radial_scale = nominal.screen.radial_scale;
  blk.principal = {nominal.camera.principal_point_px.x(), nominal.camera.principal_point_px.y()};
  blk.a = nominal.camera.a_mm;
  if (brown) {
    const auto& k = std::get<model::BrownParams>(nominal.distortion).k;
    blk.distortion.assign(k.begin(), k.end());
  } else {
    blk.distortion = {std::get<model::SeidelParams>(nominal.distortion).sigma_per_mm2};
  }
  blk.balls.assign(balls.size(), {0.0, 0.0, options.datum_z_mm});
  const int n_dist = static_cast<int>(blk.distortion.size());

  const double inv_sigma = 1.0 / options.spot_sigma_px;
  const auto add_spot = [&](ceres::Problem& problem, const Observation& o) {
    const auto& ball = balls[o.ball];
    const auto make = [&](auto tag) {
      constexpr int N = decltype(tag)::value;
      BallSpotResidual<N> r{setup,  ball.radius_mm, design.re_mm, o.target->on_cone_mm, o.target->on_sphere_mm.head<2>(),
                            o.px,   inv_sigma};
      return MakeSpotCost<N>(r);
    };
    ceres::CostFunction* cost = brown ? make(std::integral_constant<int, 5>{}) : make(std::integral_constant<int, 1>{});
    problem.AddResidualBlock(cost, nullptr, {blk.pose.data(), &blk.radial_scale, blk.principal.data(), &blk.a,
                                             blk.distortion.data(), blk.balls[o.ball].data()});
  };

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = 1;  // deterministic whatever the machine
  solver.function_tolerance = 1e-12;
  solver.parameter_tolerance = 1e-12;
  solver.gradient_tolerance = 1e-12;

  // Stage 1: each ball's position with the nominal device (the balls are placed by hand; start them where their
  // own images say they are).
  for (size_t b = 0; b < balls.size(); ++b) {
    ceres::Problem problem;
    for (const auto& o : observations) {
      if (o.ball == static_cast<int>(b)) add_spot(problem, o);
    }
    for (double* block : {blk.pose.data(), &blk.radial_scale, blk.principal.data(), &blk.a, blk.distortion.data()}) {
      problem.SetParameterBlockConstant(block);
    }
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    if (!summary.IsSolutionUsable()) {
      return fail(fmt::format("{}: the ball's position could not be found ({})", balls[b].name, summary.message));
    }
  }

  // Stage 2: everything together, with the priors and the datum.
  ceres::Problem problem;
  for (const auto& o : observations) add_spot(problem, o);
  const auto& tol = options.priors;
  const double pitch_mm = nominal.camera.PitchMm();
  {
    Eigen::VectorXd mean = Eigen::Map<const Eigen::VectorXd>(nominal.screen.AsArray().data(), 6);
    Eigen::VectorXd sd(6);
    sd << tol.tilt_deg, tol.tilt_deg, tol.roll_deg, tol.lateral_mm, tol.lateral_mm, tol.axial_mm;
    problem.AddResidualBlock(Prior(mean, sd), nullptr, blk.pose.data());
    Eigen::VectorXd pp(2), pp_sd(2);
    pp << nominal.camera.principal_point_px.x(), nominal.camera.principal_point_px.y();
    pp_sd << tol.principal_point_mm / pitch_mm, tol.principal_point_mm / pitch_mm;
    problem.AddResidualBlock(Prior(pp, pp_sd), nullptr, blk.principal.data());
    problem.AddResidualBlock(Prior(Eigen::VectorXd::Constant(1, nominal.camera.a_mm),
                                   Eigen::VectorXd::Constant(1, tol.a_relative * nominal.camera.a_mm)),
                             nullptr, &blk.a);
    problem.AddResidualBlock(Prior(Eigen::VectorXd::Constant(1, nominal.screen.radial_scale),
                                   Eigen::VectorXd::Constant(1, tol.radial_scale)),
                             nullptr, &blk.radial_scale);
    Eigen::VectorXd dm = Eigen::Map<const Eigen::VectorXd>(blk.distortion.data(), n_dist);
    Eigen::VectorXd dsd = Eigen::VectorXd::Constant(n_dist, brown ? tol.brown_k : tol.sigma_per_mm2);
    problem.AddResidualBlock(Prior(dm, dsd), nullptr, blk.distortion.data());
    for (size_t b = 0; b < balls.size(); ++b) {
      const Eigen::Vector3d start(blk.balls[b][0], blk.balls[b][1], blk.balls[b][2]);
      problem.AddResidualBlock(Prior(start, Eigen::Vector3d::Constant(tol.ball_placement_mm)), nullptr,
                               blk.balls[b].data());
    }
  }
  // The datum: the vertex z of one ball. Its stage-1 estimate is replaced by the datum value.
  blk.balls[options.datum_ball][2] = options.datum_z_mm;
  problem.SetManifold(blk.balls[options.datum_ball].data(), new ceres::SubsetManifold(3, {2}));
  if (!options.fit_radial_scale) problem.SetParameterBlockConstant(&blk.radial_scale);
  if (!options.fit_distortion) {
    problem.SetParameterBlockConstant(blk.distortion.data());
  } else if (brown) {
    problem.SetManifold(blk.distortion.data(), new ceres::SubsetManifold(5, {2, 3, 4}));
    fit.notes.push_back(
        "Brown p1, p2 and k3 held at their nominal values: ball images alone cannot separate decentring distortion "
        "from a screen tilt; calibrate them from target views");
  }
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  fit.iterations = static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable() || summary.termination_type == ceres::NO_CONVERGENCE) {
    return fail(fmt::format("the device fit did not converge ({})", summary.message));
  }

  // Residuals per ball and chi^2 of the spots alone.
  std::vector<double> ssr(balls.size(), 0.0);
  double chi2 = 0;
  for (const auto& o : observations) {
    const auto& ball = balls[o.ball];
    double px[2];
    const Eigen::Vector2d initial = o.target->on_sphere_mm.head<2>() * (ball.radius_mm / design.re_mm) +
                                    Eigen::Vector2d(blk.balls[o.ball][0], blk.balls[o.ball][1]);
    if (!model::ProjectBallSpot(setup, blk.pose.data(), &blk.radial_scale, blk.principal.data(), &blk.a,
                                blk.distortion.data(), blk.balls[o.ball].data(), ball.radius_mm,
                                o.target->on_cone_mm.data(), initial, px)) {
      return fail(fmt::format("{}: spot ({}, {}) no longer images through the fitted device", ball.name,
                              o.target->id.ring, o.target->id.index));
    }
    const double r2 = std::pow(px[0] - o.px.x(), 2) + std::pow(px[1] - o.px.y(), 2);
    ssr[o.ball] += r2;
    chi2 += r2 * inv_sigma * inv_sigma;
  }
  for (size_t b = 0; b < balls.size(); ++b) fit.ball_rms_px.push_back(std::sqrt(ssr[b] / fit.ball_spots[b]));

  // The device parameters reported, in order, with their block and index.
  struct Entry {
    std::string name;
    double* block;
    int index;
    double nominal;
  };
  std::vector<Entry> entries = {
      {"rx_deg", blk.pose.data(), 0, nominal.screen.rx_deg}, {"ry_deg", blk.pose.data(), 1, nominal.screen.ry_deg},
      {"rz_deg", blk.pose.data(), 2, nominal.screen.rz_deg}, {"tx_mm", blk.pose.data(), 3, nominal.screen.tx_mm},
      {"ty_mm", blk.pose.data(), 4, nominal.screen.ty_mm},   {"tz_mm", blk.pose.data(), 5, nominal.screen.tz_mm}};
  if (options.fit_radial_scale) entries.push_back({"radial_scale", &blk.radial_scale, 0, nominal.screen.radial_scale});
  entries.push_back({"principal_point_u_px", blk.principal.data(), 0, nominal.camera.principal_point_px.x()});
  entries.push_back({"principal_point_v_px", blk.principal.data(), 1, nominal.camera.principal_point_px.y()});
  entries.push_back({"a_mm", &blk.a, 0, nominal.camera.a_mm});
  if (options.fit_distortion) {
    if (brown) {
      entries.push_back({"k1", blk.distortion.data(), 0, blk.distortion[0]});
      entries.push_back({"k2", blk.distortion.data(), 1, blk.distortion[1]});
      const auto& k = std::get<model::BrownParams>(nominal.distortion).k;
      entries[entries.size() - 2].nominal = k[0];
      entries.back().nominal = k[1];
    } else {
      entries.push_back({"sigma_per_mm2", blk.distortion.data(), 0,
                         std::get<model::SeidelParams>(nominal.distortion).sigma_per_mm2});
    }
  }
  int free_params = 0;
  for (const auto& e : entries) (void)e, ++free_params;
  free_params += 3 * static_cast<int>(balls.size()) - 1;
  fit.dof = 2 * static_cast<int>(observations.size()) - free_params;
  if (fit.dof < 1) return fail(fmt::format("{} spot coordinates for {} parameters", 2 * observations.size(), free_params));
  fit.chi2_per_dof = chi2 / fit.dof;
  fit.stddev_scale = std::max(1.0, std::sqrt(fit.chi2_per_dof));

  // Covariance of the free parameters: (J^T J)^-1 from the Jacobian of every residual (spots and priors) in the
  // tangent space of the blocks (calib/jacobian_covariance.h says why not ceres::Covariance).
  std::vector<double*> blocks = {blk.pose.data(), blk.principal.data(), &blk.a};
  if (options.fit_radial_scale) blocks.push_back(&blk.radial_scale);
  if (options.fit_distortion) blocks.push_back(blk.distortion.data());
  for (auto& b : blk.balls) blocks.push_back(b.data());
  const TangentCovarianceResult covariance = TangentCovariance(problem, blocks);
  if (!covariance.ok) {
    return fail("the device fit's covariance failed: " + covariance.message +
                " (a parameter is not determined by these images)");
  }
  const Eigen::MatrixXd& tangent_cov = covariance.matrix;
  // Which ambient components are free, per block, in tangent order.
  std::map<const double*, std::vector<int>> free_components;
  {
    int col = 0;
    for (double* b : blocks) {
      const int size = problem.ParameterBlockSize(b);
      std::vector<int> held;
      if (b == blk.balls[options.datum_ball].data()) held = {2};
      if (brown && b == blk.distortion.data()) held = {2, 3, 4};
      std::vector<int> cols(size, -1);
      for (int i = 0; i < size; ++i) {
        if (std::find(held.begin(), held.end(), i) == held.end()) cols[i] = col++;
      }
      free_components[b] = cols;
    }
    if (col != tangent_cov.rows()) return fail("internal: the covariance's columns do not match the parameters");
  }
  const auto cov_entry = [&](const Entry& a, const Entry& b) {
    const int i = free_components.at(a.block)[a.index], j = free_components.at(b.block)[b.index];
    return (i < 0 || j < 0) ? 0.0 : tangent_cov(i, j);
  };
  const int n = static_cast<int>(entries.size());
  fit.covariance.resize(n, n);
  const double scale2 = fit.stddev_scale * fit.stddev_scale;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) fit.covariance(i, j) = scale2 * cov_entry(entries[i], entries[j]);
  }
  for (int i = 0; i < n; ++i) {
    const auto& e = entries[i];
    fit.parameters.push_back({e.name, e.block[e.index], std::sqrt(std::max(0.0, fit.covariance(i, i))), e.nominal});
  }
  for (size_t b = 0; b < balls.size(); ++b) {
    Eigen::Vector3d sd;
    for (int k = 0; k < 3; ++k) {
      const int i = free_components.at(blk.balls[b].data())[k];
      sd[k] = i < 0 ? 0.0 : fit.stddev_scale * std::sqrt(std::max(0.0, tangent_cov(i, i)));
    }
    fit.ball_vertex_mm.emplace_back(blk.balls[b][0], blk.balls[b][1], blk.balls[b][2]);
    fit.ball_vertex_stddev_mm.push_back(sd);
  }

  // The calibrated device.
  fit.device.screen = model::ScreenPose::FromArray(blk.pose.data(), blk.radial_scale);
  fit.device.camera.principal_point_px = {blk.principal[0], blk.principal[1]};
  fit.device.camera.a_mm = blk.a;
  if (brown) {
    auto b = std::get<model::BrownParams>(nominal.distortion);
    std::copy(blk.distortion.begin(), blk.distortion.end(), b.k.begin());
    b.focal_mm = blk.a;
    fit.device.distortion = b;
  } else {
    auto s = std::get<model::SeidelParams>(nominal.distortion);
    s.sigma_per_mm2 = blk.distortion[0];
    fit.device.distortion = s;
  }
  fit.gauge = fmt::format(
      "axial gauge (balls and screen along the axis with a in proportion) fixed by the datum: ball {} ({}) vertex "
      "at z = {} mm",
      options.datum_ball + 1, balls[options.datum_ball].name, options.datum_z_mm);
  if (const auto invalid = fit.device.Invalid()) return fail("the fitted device is not physical: " + *invalid);
  fit.model_adequate = fit.chi2_per_dof <= options.max_chi2_per_dof;
  fit.ok = true;
  fit.message = fmt::format("{} balls, {} spots, chi2/dof {:.3g}, {} iterations{}", balls.size(), observations.size(),
                            fit.chi2_per_dof, fit.iterations,
                            fit.model_adequate ? ""
                                               : fmt::format(" — chi2/dof above {}: the device model does not "
                                                             "describe these images (non-conical screen? wrong radius? "
                                                             "spot noise larger than {} px?)",
                                                             options.max_chi2_per_dof, options.spot_sigma_px));
  return fit;
}

}  // namespace topocal::calib
