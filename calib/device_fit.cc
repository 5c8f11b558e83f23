#include "calib/device_fit.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>

#include <ceres/ceres.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/calib3d.hpp>

#include "calib/device_fit_residuals.h"
#include "calib/estimate_table.h"
#include "calib/jacobian_covariance.h"

namespace topocal::calib {
namespace {

using device_fit::BallSpotResidual;
using device_fit::CornerResidual;
using device_fit::MakeCornerCost;
using device_fit::MakeSpotCost;
using device_fit::Prior;

// Minimum identified spots per ball image: below ~a ring's worth the ball's three coordinates and the device share
// too little; the paper's design images 624.
constexpr int kMinSpotsPerBall = 24;
// Minimum corners per target view: a board pose (6 numbers) and some redundancy.
constexpr int kMinCornersPerView = 12;

// The parameter blocks of the fit.
struct Blocks {
  std::array<double, model::ScreenPose::kNumParams> pose{};
  double radial_scale = 1;
  std::array<double, 2> principal{};
  double a = 0;
  std::vector<double> distortion;   // 1 (Seidel sigma) or the lens model's coefficients
  std::vector<std::array<double, 3>> balls;
  double z_offset = 0;  // added to every ball's z: fitted with stage steps, held at 0 with the datum
  std::vector<std::array<double, 6>> boards;  // per target view: angle-axis (rad), translation (mm)
};

struct Observation {
  int ball;
  const model::TargetPoint* target;
  Eigen::Vector2d px;
};

struct CornerSeen {
  int view;
  Eigen::Vector3d board_mm;
  Eigen::Vector2d px;
};

// One fit of a device to ball images: its parameter blocks, the identified spots and the two Ceres stages. Each step
// is a member so that FitDevice reads as the sequence it is.
// A lens model's k1 and k2 are what ball images determine; its later coefficients (p1, p2, k3, ...) are held.
constexpr int kFittedLensCoefficients = 2;

class DeviceFitter {
 public:
  DeviceFitter(const model::Device& nominal, const model::TopographerParams& design, const std::vector<BallView>& balls,
               const std::vector<ViewObservations>& views, const DeviceFitOptions& options)
      : nominal_(nominal), design_(design), balls_(balls), views_(views), options_(options),
        setup_(model::ProjectionSetupOf(nominal, design)), lens_(setup_.Lens()), inv_sigma_(1.0 / options.spot_sigma_px),
        inv_corner_sigma_(1.0 / options.corner_sigma_px) {
    solver_.linear_solver_type = ceres::DENSE_QR;
    solver_.max_num_iterations = options.max_iterations;
    solver_.num_threads = 1;  // deterministic whatever the machine
    solver_.function_tolerance = 1e-12;
    solver_.parameter_tolerance = 1e-12;
    solver_.gradient_tolerance = 1e-12;
  }

  // The lens model's coefficients the fit determines: k1, k2 from balls alone, every one with target views.
  int FittedLensCoefficients() const {
    return views_.empty() ? kFittedLensCoefficients : model::LensParameterCount(*lens_);
  }
  // The held components of the lens model's block: the coefficients after those.
  std::vector<int> HeldLensComponents() const {
    std::vector<int> held;
    for (int i = FittedLensCoefficients(); i < model::LensParameterCount(*lens_); ++i) held.push_back(i);
    return held;
  }

  std::optional<std::string> CollectSpots(const std::vector<model::TargetPoint>& designed_targets, DeviceFit* fit);
  void StartBlocks();
  std::optional<std::string> CollectCorners(DeviceFit* fit);
  std::optional<std::string> LocateBalls();
  std::optional<std::string> LocateBoards();
  std::optional<std::string> SolveAll(DeviceFit* fit);
  bool Steps() const { return !options_.ball_steps_mm.empty(); }
  void HoldTheGauge();
  std::optional<std::string> SpotResiduals(DeviceFit* fit) const;
  std::optional<std::string> CornerResiduals(DeviceFit* fit, double* chi2) const;
  std::optional<std::string> Covariance(DeviceFit* fit);
  void FittedDevice(DeviceFit* fit) const;
  size_t spots() const { return observations_.size(); }

 private:
  void AddSpot(ceres::Problem& problem, const Observation& o);
  void AddCorner(ceres::Problem& problem, const CornerSeen& c);
  std::vector<double*> DeviceBlocks() { return {blk_.pose.data(), &blk_.radial_scale, blk_.principal.data(), &blk_.a,
                                                blk_.distortion.data()}; }
  void AddPriors(ceres::Problem& problem);
  EstimateTable ReportedTable(std::vector<double>* nominal) const;

  const model::Device& nominal_;
  const model::TopographerParams& design_;
  const std::vector<BallView>& balls_;
  const std::vector<ViewObservations>& views_;
  const DeviceFitOptions& options_;
  const model::DeviceProjectionSetup setup_;
  const std::optional<model::LensModelId> lens_;  // the distortion block's lens model; empty: Seidel
  const double inv_sigma_, inv_corner_sigma_;
  ceres::Solver::Options solver_;
  std::vector<Observation> observations_;
  std::vector<CornerSeen> corners_;
  Blocks blk_;
  ceres::Problem problem_;  // stage 2: everything together, kept for the covariance
};

std::optional<std::string> DeviceFitter::CollectSpots(const std::vector<model::TargetPoint>& designed_targets,
                                                      DeviceFit* fit) {
  std::map<model::SpotId, const model::TargetPoint*> target_of;
  for (const auto& t : designed_targets) target_of[t.id] = &t;
  for (size_t b = 0; b < balls_.size(); ++b) {
    const auto& ball = balls_[b];
    if (!(ball.radius_mm > 0) || !std::isfinite(ball.radius_mm)) {
      return fmt::format("{}: ball radius must be > 0 (got {})", ball.name, ball.radius_mm);
    }
    int used = 0;
    for (const auto& [id, px] : ball.spots_px) {
      const auto it = target_of.find(id);
      if (it == target_of.end() || !px.allFinite()) continue;
      observations_.push_back({static_cast<int>(b), it->second, px});
      ++used;
    }
    if (used < kMinSpotsPerBall) {
      return fmt::format("{}: {} identified spots, at least {} needed", ball.name, used, kMinSpotsPerBall);
    }
    fit->ball_spots.push_back(used);
  }
  return std::nullopt;
}

std::optional<std::string> DeviceFitter::CollectCorners(DeviceFit* fit) {
  for (size_t v = 0; v < views_.size(); ++v) {
    const auto& view = views_[v];
    if (view.image_width != nominal_.camera.width_px || view.image_height != nominal_.camera.height_px) {
      return fmt::format("{}: {} x {} px, but the device's sensor is {} x {} px", view.image_path, view.image_width,
                         view.image_height, nominal_.camera.width_px, nominal_.camera.height_px);
    }
    int used = 0;
    for (const auto& c : view.corners) {
      if (!c.image_px.allFinite() || !c.target_mm.allFinite()) continue;
      corners_.push_back({static_cast<int>(v), c.target_mm, c.image_px});
      ++used;
    }
    if (used < kMinCornersPerView) {
      return fmt::format("{}: {} target corners, at least {} needed", view.image_path, used, kMinCornersPerView);
    }
    fit->view_corners.push_back(used);
  }
  return std::nullopt;
}

void DeviceFitter::StartBlocks() {
  blk_.pose = nominal_.screen.AsArray();
  blk_.radial_scale = nominal_.screen.radial_scale;
  blk_.principal = {nominal_.camera.principal_point_px.x(), nominal_.camera.principal_point_px.y()};
  blk_.a = nominal_.camera.a_mm;
  if (lens_) {
    const auto& k = std::get<model::LensParams>(nominal_.distortion).k;
    blk_.distortion.assign(k.begin(), k.begin() + model::LensParameterCount(*lens_));
  } else {
    blk_.distortion = {std::get<model::SeidelParams>(nominal_.distortion).sigma_per_mm2};
  }
  blk_.balls.assign(balls_.size(), {0.0, 0.0, options_.datum_z_mm});
  blk_.boards.assign(views_.size(), {});
}

void DeviceFitter::AddCorner(ceres::Problem& problem, const CornerSeen& c) {
  const auto make = [&](auto tag) {
    constexpr int N = decltype(tag)::value;
    return MakeCornerCost<N>(CornerResidual<N>{setup_, c.board_mm, c.px, inv_corner_sigma_});
  };
  ceres::CostFunction* cost =
      lens_ ? std::visit([&](auto m) { return make(std::integral_constant<int, decltype(m)::kNumParams>{}); }, *lens_)
            : make(std::integral_constant<int, 1>{});
  problem.AddResidualBlock(cost, nullptr,
                           {blk_.boards[c.view].data(), blk_.principal.data(), &blk_.a, blk_.distortion.data()});
}

// Stage 1 for the target views: each board's pose with the nominal device. The start is OpenCV's PnP through the
// nominal pinhole without distortion: the device maps a point to the pixel principal + M (-a x / depth) / pitch, so
// the observed pixels, turned back by the orientation M and mirrored about the principal point, are a plain
// pinhole's with fx = a / pitch_u, fy = a / pitch_v in the frame whose origin is the pinhole (z + b).
std::optional<std::string> DeviceFitter::LocateBoards() {
  const auto& cam = nominal_.camera;
  const Eigen::Vector2d pp = cam.principal_point_px;
  const Eigen::Vector2d pitches_mm = cam.PitchesMm();
  const cv::Matx33d k(cam.a_mm / pitches_mm.x(), 0, pp.x(), 0, cam.a_mm / pitches_mm.y(), pp.y(), 0, 0, 1);
  for (size_t v = 0; v < views_.size(); ++v) {
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const auto& c : corners_) {
      if (c.view != static_cast<int>(v)) continue;
      const Eigen::Vector2d q = pp - cam.Orientation().transpose() * (c.px - pp);
      object.emplace_back(c.board_mm.x(), c.board_mm.y(), c.board_mm.z());
      image.emplace_back(q.x(), q.y());
    }
    cv::Vec3d rvec, tvec;
    if (!cv::solvePnP(object, image, k, cv::noArray(), rvec, tvec) || !(tvec[2] > 0)) {
      return fmt::format("{}: the target's pose could not be found", views_[v].image_path);
    }
    blk_.boards[v] = {rvec[0], rvec[1], rvec[2], tvec[0], tvec[1], tvec[2] - setup_.b_mm};
    ceres::Problem problem;
    for (const auto& c : corners_) {
      if (c.view == static_cast<int>(v)) AddCorner(problem, c);
    }
    for (double* block : {blk_.principal.data(), &blk_.a, blk_.distortion.data()}) {
      problem.SetParameterBlockConstant(block);
    }
    ceres::Solver::Summary summary;
    ceres::Solve(solver_, &problem, &summary);
    if (!summary.IsSolutionUsable()) {
      return fmt::format("{}: the target's pose could not be found ({})", views_[v].image_path, summary.message);
    }
  }
  return std::nullopt;
}

void DeviceFitter::AddSpot(ceres::Problem& problem, const Observation& o) {
  const auto& ball = balls_[o.ball];
  const auto make = [&](auto tag) {
    constexpr int N = decltype(tag)::value;
    BallSpotResidual<N> r{setup_, ball.radius_mm, design_.re_mm, o.target->on_cone_mm,
                          o.target->on_sphere_mm.head<2>(), o.px, inv_sigma_};
    return MakeSpotCost<N>(r);
  };
  ceres::CostFunction* cost =
      lens_ ? std::visit([&](auto m) { return make(std::integral_constant<int, decltype(m)::kNumParams>{}); }, *lens_)
            : make(std::integral_constant<int, 1>{});
  problem.AddResidualBlock(cost, nullptr, {blk_.pose.data(), &blk_.radial_scale, blk_.principal.data(), &blk_.a,
                                           blk_.distortion.data(), blk_.balls[o.ball].data(), &blk_.z_offset});
}

// Stage 1: each ball's position with the nominal device (the balls are placed by hand; start them where their own
// images say they are).
std::optional<std::string> DeviceFitter::LocateBalls() {
  for (size_t b = 0; b < balls_.size(); ++b) {
    ceres::Problem problem;
    for (const auto& o : observations_) {
      if (o.ball == static_cast<int>(b)) AddSpot(problem, o);
    }
    for (double* block : DeviceBlocks()) problem.SetParameterBlockConstant(block);
    problem.SetParameterBlockConstant(&blk_.z_offset);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_, &problem, &summary);
    if (!summary.IsSolutionUsable()) {
      return fmt::format("{}: the ball's position could not be found ({})", balls_[b].name, summary.message);
    }
  }
  return std::nullopt;
}

void DeviceFitter::AddPriors(ceres::Problem& problem) {
  const auto& tol = options_.priors;
  const double pitch_mm = nominal_.camera.PitchMm();
  const int n_dist = static_cast<int>(blk_.distortion.size());
  Eigen::VectorXd mean = Eigen::Map<const Eigen::VectorXd>(nominal_.screen.AsArray().data(), 6);
  Eigen::VectorXd sd(6);
  sd << tol.tilt_deg, tol.tilt_deg, tol.roll_deg, tol.lateral_mm, tol.lateral_mm, tol.axial_mm;
  problem.AddResidualBlock(Prior(mean, sd), nullptr, blk_.pose.data());
  Eigen::VectorXd pp(2), pp_sd(2);
  pp << nominal_.camera.principal_point_px.x(), nominal_.camera.principal_point_px.y();
  pp_sd << tol.principal_point_mm / pitch_mm, tol.principal_point_mm / pitch_mm;
  problem.AddResidualBlock(Prior(pp, pp_sd), nullptr, blk_.principal.data());
  problem.AddResidualBlock(Prior(Eigen::VectorXd::Constant(1, nominal_.camera.a_mm),
                                 Eigen::VectorXd::Constant(1, tol.a_relative * nominal_.camera.a_mm)),
                           nullptr, &blk_.a);
  problem.AddResidualBlock(Prior(Eigen::VectorXd::Constant(1, nominal_.screen.radial_scale),
                                 Eigen::VectorXd::Constant(1, tol.radial_scale)),
                           nullptr, &blk_.radial_scale);
  Eigen::VectorXd dm = Eigen::Map<const Eigen::VectorXd>(blk_.distortion.data(), n_dist);
  Eigen::VectorXd dsd = Eigen::VectorXd::Constant(n_dist, lens_ ? tol.brown_k : tol.sigma_per_mm2);
  problem.AddResidualBlock(Prior(dm, dsd), nullptr, blk_.distortion.data());
  for (size_t b = 0; b < balls_.size(); ++b) {
    const Eigen::Vector3d start(blk_.balls[b][0], blk_.balls[b][1], blk_.balls[b][2]);
    problem.AddResidualBlock(Prior(start, Eigen::Vector3d::Constant(tol.ball_placement_mm)), nullptr,
                             blk_.balls[b].data());
  }
}

// The axial gauge. The datum: one ball's vertex z, its stage-1 estimate replaced by the datum value, the offset held
// at 0. The stage steps: every ball's z held at its step, the offset free (starting where stage 1 put the balls on
// average) with the balls' weak placement prior.
void DeviceFitter::HoldTheGauge() {
  if (!Steps()) {
    blk_.balls[options_.datum_ball][2] = options_.datum_z_mm;
    problem_.SetManifold(blk_.balls[options_.datum_ball].data(), new ceres::SubsetManifold(3, {2}));
    problem_.SetParameterBlockConstant(&blk_.z_offset);
    return;
  }
  double offset = 0;
  for (size_t b = 0; b < balls_.size(); ++b) offset += blk_.balls[b][2] - options_.ball_steps_mm[b];
  blk_.z_offset = offset / static_cast<double>(balls_.size());
  for (size_t b = 0; b < balls_.size(); ++b) {
    blk_.balls[b][2] = options_.ball_steps_mm[b];
    problem_.SetManifold(blk_.balls[b].data(), new ceres::SubsetManifold(3, {2}));
  }
  problem_.AddResidualBlock(Prior(Eigen::VectorXd::Constant(1, blk_.z_offset),
                                  Eigen::VectorXd::Constant(1, options_.priors.ball_placement_mm)),
                            nullptr, &blk_.z_offset);
}

// Stage 2: everything together, with the priors and the gauge.
std::optional<std::string> DeviceFitter::SolveAll(DeviceFit* fit) {
  for (const auto& o : observations_) AddSpot(problem_, o);
  for (const auto& c : corners_) AddCorner(problem_, c);
  AddPriors(problem_);
  HoldTheGauge();
  if (!options_.fit_radial_scale) problem_.SetParameterBlockConstant(&blk_.radial_scale);
  if (!options_.fit_distortion) {
    problem_.SetParameterBlockConstant(blk_.distortion.data());
  } else if (lens_ && !views_.empty()) {
    fit->notes.push_back(fmt::format("{} {} fitted with the screen pose from {} ball and {} target views",
                                     model::LensModelName(*lens_), fmt::join(model::LensParameterNames(*lens_), ", "),
                                     balls_.size(), views_.size()));
  } else if (lens_) {
    problem_.SetManifold(blk_.distortion.data(),
                         new ceres::SubsetManifold(static_cast<int>(blk_.distortion.size()), HeldLensComponents()));
    const auto names = model::LensParameterNames(*lens_).subspan(kFittedLensCoefficients);
    fit->notes.push_back(fmt::format(
        "{} {} and {} held at their nominal values: ball images alone cannot separate decentring distortion "
        "from a screen tilt; calibrate them from target views",
        model::LensModelName(*lens_), fmt::join(names.first(names.size() - 1), ", "), names.back()));
  }
  ceres::Solver::Summary summary;
  ceres::Solve(solver_, &problem_, &summary);
  fit->iterations = static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable() || summary.termination_type == ceres::NO_CONVERGENCE) {
    return fmt::format("the device fit did not converge ({})", summary.message);
  }
  return std::nullopt;
}

// Residuals per ball (and per target view) and chi^2 of the spots and corners (the priors excluded); the degrees of
// freedom.
std::optional<std::string> DeviceFitter::SpotResiduals(DeviceFit* fit) const {
  std::vector<double> ssr(balls_.size(), 0.0);
  double chi2 = 0;
  for (const auto& o : observations_) {
    const auto& ball = balls_[o.ball];
    double px[2];
    const Eigen::Vector2d initial = o.target->on_sphere_mm.head<2>() * (ball.radius_mm / design_.re_mm) +
                                    Eigen::Vector2d(blk_.balls[o.ball][0], blk_.balls[o.ball][1]);
    const auto& b = blk_.balls[o.ball];
    const double vertex[3] = {b[0], b[1], b[2] + blk_.z_offset};
    if (!model::ProjectBallSpot(setup_, blk_.pose.data(), &blk_.radial_scale, blk_.principal.data(), &blk_.a,
                                blk_.distortion.data(), vertex, ball.radius_mm,
                                o.target->on_cone_mm.data(), initial, px)) {
      return fmt::format("{}: spot ({}, {}) no longer images through the fitted device", ball.name,
                         o.target->id.ring, o.target->id.index);
    }
    const double r2 = std::pow(px[0] - o.px.x(), 2) + std::pow(px[1] - o.px.y(), 2);
    ssr[o.ball] += r2;
    chi2 += r2 * inv_sigma_ * inv_sigma_;
  }
  for (size_t b = 0; b < balls_.size(); ++b) fit->ball_rms_px.push_back(std::sqrt(ssr[b] / fit->ball_spots[b]));
  if (auto e = CornerResiduals(fit, &chi2)) return e;
  // The reported parameters, 3 coordinates per ball less the datum (or with steps: 2 per ball and the offset), 6 per
  // board.
  const int ball_params = Steps() ? 2 * static_cast<int>(balls_.size()) + 1 : 3 * static_cast<int>(balls_.size()) - 1;
  const int free_params =
      ReportedTable(nullptr).size() + ball_params + 6 * static_cast<int>(views_.size());
  const int coordinates = 2 * static_cast<int>(observations_.size() + corners_.size());
  fit->dof = coordinates - free_params;
  if (fit->dof < 1) return fmt::format("{} spot and corner coordinates for {} parameters", coordinates, free_params);
  fit->chi2_per_dof = chi2 / fit->dof;
  fit->stddev_scale = std::max(1.0, std::sqrt(fit->chi2_per_dof));
  return std::nullopt;
}

// Residuals per target view; their chi^2 added to *chi2.
std::optional<std::string> DeviceFitter::CornerResiduals(DeviceFit* fit, double* chi2) const {
  std::vector<double> ssr(views_.size(), 0.0);
  for (const auto& c : corners_) {
    double r[2];  // the residual in pixels (the model's operator() does not depend on the block size)
    if (!CornerResidual<1>{setup_, c.board_mm, c.px, 1.0}(blk_.boards[c.view].data(), blk_.principal.data(), &blk_.a,
                                                          blk_.distortion.data(), r)) {
      return fmt::format("{}: a target corner no longer images through the fitted device", views_[c.view].image_path);
    }
    const double r2 = r[0] * r[0] + r[1] * r[1];
    ssr[c.view] += r2;
    *chi2 += r2 * inv_corner_sigma_ * inv_corner_sigma_;
  }
  for (size_t v = 0; v < views_.size(); ++v) fit->view_rms_px.push_back(std::sqrt(ssr[v] / fit->view_corners[v]));
  return std::nullopt;
}

// The device parameters reported, in order, and (if asked) their nominal values.
EstimateTable DeviceFitter::ReportedTable(std::vector<double>* nominal) const {
  const auto& screen = nominal_.screen;
  EstimateTable table;
  std::vector<double> nominals;
  const auto add = [&](std::string name, const double* block, int index, double value) {
    table.Add(std::move(name), block, index);
    nominals.push_back(value);
  };
  const char* pose_names[] = {"rx_deg", "ry_deg", "rz_deg", "tx_mm", "ty_mm", "tz_mm"};
  const auto pose = screen.AsArray();
  for (int i = 0; i < model::ScreenPose::kNumParams; ++i) add(pose_names[i], blk_.pose.data(), i, pose[i]);
  if (options_.fit_radial_scale) add("radial_scale", &blk_.radial_scale, 0, screen.radial_scale);
  add("principal_point_u_px", blk_.principal.data(), 0, nominal_.camera.principal_point_px.x());
  add("principal_point_v_px", blk_.principal.data(), 1, nominal_.camera.principal_point_px.y());
  add("a_mm", &blk_.a, 0, nominal_.camera.a_mm);
  if (options_.fit_distortion && lens_) {
    const auto& k = std::get<model::LensParams>(nominal_.distortion).k;
    const auto names = model::LensParameterNames(*lens_);
    for (int i = 0; i < FittedLensCoefficients(); ++i) {
      add(std::string(names[static_cast<size_t>(i)]), blk_.distortion.data(), i, k[static_cast<size_t>(i)]);
    }
  } else if (options_.fit_distortion) {
    add("sigma_per_mm2", blk_.distortion.data(), 0, std::get<model::SeidelParams>(nominal_.distortion).sigma_per_mm2);
  }
  if (nominal) *nominal = std::move(nominals);
  return table;
}

// Covariance of the reported parameters and the balls' vertices: (J^T J)^-1 from the Jacobian of every residual
// (spots, corners and priors) in the tangent space of the blocks (calib/jacobian_covariance.h says why not
// ceres::Covariance), scaled by stddev_scale^2.
std::optional<std::string> DeviceFitter::Covariance(DeviceFit* fit) {
  std::vector<double*> blocks = {blk_.pose.data(), blk_.principal.data(), &blk_.a};
  if (options_.fit_radial_scale) blocks.push_back(&blk_.radial_scale);
  if (options_.fit_distortion) blocks.push_back(blk_.distortion.data());
  for (auto& b : blk_.balls) blocks.push_back(b.data());
  if (Steps()) blocks.push_back(&blk_.z_offset);
  for (auto& b : blk_.boards) blocks.push_back(b.data());
  const TangentCovarianceResult covariance = TangentCovariance(problem_, blocks);
  if (!covariance.ok) {
    return "the device fit's covariance failed: " + covariance.message +
           " (a parameter is not determined by these images)";
  }
  std::vector<double> nominal;
  const EstimateTable table = ReportedTable(&nominal);
  std::string why;
  const auto cov = table.Covariance(problem_, blocks, covariance, fit->stddev_scale * fit->stddev_scale, &why);
  if (!cov) return "the device fit's covariance failed: " + why;
  fit->covariance = *cov;
  const auto names = table.Names();
  const auto values = table.Values();
  const auto sd = EstimateTable::StandardDeviations(fit->covariance);
  for (int i = 0; i < table.size(); ++i) {
    const auto k = static_cast<size_t>(i);
    fit->parameters.push_back({names[k], values[k], sd[k], nominal[k]});
  }
  // Each ball's vertex; with stage steps its z is the fitted offset plus the known step.
  EstimateTable vertices;
  for (auto& b : blk_.balls) {
    vertices.Add("x_mm", b.data(), 0);
    vertices.Add("y_mm", b.data(), 1);
    if (Steps()) {
      vertices.Add("z_mm", &blk_.z_offset, 0);
    } else {
      vertices.Add("z_mm", b.data(), 2);
    }
  }
  const auto vertex_cov = vertices.Covariance(problem_, blocks, covariance, 1.0, &why);
  if (!vertex_cov) return "the device fit's covariance failed: " + why;
  const auto vertex_sd = EstimateTable::StandardDeviations(*vertex_cov);
  for (size_t b = 0; b < balls_.size(); ++b) {
    fit->ball_vertex_mm.emplace_back(blk_.balls[b][0], blk_.balls[b][1], blk_.balls[b][2] + blk_.z_offset);
    fit->ball_vertex_stddev_mm.emplace_back(fit->stddev_scale * vertex_sd[3 * b],
                                            fit->stddev_scale * vertex_sd[3 * b + 1],
                                            fit->stddev_scale * vertex_sd[3 * b + 2]);
  }
  return std::nullopt;
}

// The calibrated device and how its gauge was fixed.
void DeviceFitter::FittedDevice(DeviceFit* fit) const {
  fit->device.screen = model::ScreenPose::FromArray(blk_.pose.data(), blk_.radial_scale);
  fit->device.camera.principal_point_px = {blk_.principal[0], blk_.principal[1]};
  fit->device.camera.a_mm = blk_.a;
  if (lens_) {
    auto b = std::get<model::LensParams>(nominal_.distortion);
    std::copy(blk_.distortion.begin(), blk_.distortion.end(), b.k.begin());
    b.focal_mm = blk_.a;
    fit->device.distortion = b;
  } else {
    auto s = std::get<model::SeidelParams>(nominal_.distortion);
    s.sigma_per_mm2 = blk_.distortion[0];
    fit->device.distortion = s;
  }
  if (Steps()) {
    fit->gauge = fmt::format(
        "axial gauge (balls and screen along the axis with a in proportion) fixed by the balls' known stage steps "
        "({} mm): ball 1 ({}) vertex at z = {:.4f} +- {:.2g} mm",
        fmt::join(options_.ball_steps_mm, ", "), balls_[0].name, fit->ball_vertex_mm[0].z(),
        fit->ball_vertex_stddev_mm[0].z());
    return;
  }
  fit->gauge = fmt::format(
      "axial gauge (balls and screen along the axis with a in proportion) fixed by the datum: ball {} ({}) vertex "
      "at z = {} mm",
      options_.datum_ball + 1, balls_[options_.datum_ball].name, options_.datum_z_mm);
}

}  // namespace

DeviceFit FitDevice(const model::Device& nominal, const model::TopographerParams& design,
                    const std::vector<model::TargetPoint>& designed_targets, const std::vector<BallView>& balls,
                    const DeviceFitOptions& options, const std::vector<ViewObservations>& views) {
  DeviceFit fit;
  fit.device = nominal;
  const auto fail = [&fit](std::string m) {
    fit.ok = false;
    fit.message = std::move(m);
    return fit;
  };
  std::string why;
  if (!options.IsValid(&why)) return fail("invalid options: " + why);
  if (balls.empty()) return fail("no ball images");
  if (!options.ball_steps_mm.empty() && options.ball_steps_mm.size() != balls.size()) {
    return fail(fmt::format("{} stage steps for {} ball images (one per ball, in their order)",
                            options.ball_steps_mm.size(), balls.size()));
  }
  if (options.datum_ball >= static_cast<int>(balls.size())) {
    return fail(fmt::format("datum ball {} but only {} ball images", options.datum_ball + 1, balls.size()));
  }
  DeviceFitter fitter(nominal, design, balls, views, options);
  if (auto e = fitter.CollectSpots(designed_targets, &fit)) return fail(std::move(*e));
  if (auto e = fitter.CollectCorners(&fit)) return fail(std::move(*e));
  fitter.StartBlocks();
  if (auto e = fitter.LocateBalls()) return fail(std::move(*e));
  if (auto e = fitter.LocateBoards()) return fail(std::move(*e));
  if (auto e = fitter.SolveAll(&fit)) return fail(std::move(*e));
  if (auto e = fitter.SpotResiduals(&fit)) return fail(std::move(*e));
  if (auto e = fitter.Covariance(&fit)) return fail(std::move(*e));
  fitter.FittedDevice(&fit);
  if (const auto invalid = fit.device.Invalid()) return fail("the fitted device is not physical: " + *invalid);
  fit.model_adequate = fit.chi2_per_dof <= options.max_chi2_per_dof;
  fit.ok = true;
  fit.message = fmt::format("{} balls, {} spots{}, chi2/dof {:.3g}, {} iterations{}", balls.size(), fitter.spots(),
                            views.empty() ? "" : fmt::format(", {} target views", views.size()), fit.chi2_per_dof,
                            fit.iterations,
                            fit.model_adequate ? ""
                                               : fmt::format(" — chi2/dof above {}: the device model does not "
                                                             "describe these images (non-conical screen? wrong radius? "
                                                             "spot noise larger than {} px?)",
                                                             options.max_chi2_per_dof, options.spot_sigma_px));
  return fit;
}

}  // namespace topocal::calib
