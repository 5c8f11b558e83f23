#include "pipeline/device_calibration.h"

#include <stdexcept>

#include <fmt/format.h>

#include "correct/detect_and_index.h"
#include "model/null_screen.h"
#include "util/io.h"

namespace topocal::pipeline {

BallDetection DetectBall(const BallImage& ball, const model::Device& nominal, const model::IdealImageParams& ideal) {
  const auto located = correct::DetectAndIndexSpots(ball.image, nominal.camera, ideal);
  if (!located.ok) throw std::runtime_error(fmt::format("{}: the ball's spots could not be indexed: {}", ball.name, located.message));
  BallDetection d;
  d.view.name = ball.name;
  d.view.radius_mm = ball.radius_mm;
  for (const auto& s : located.spots) d.view.spots_px.emplace_back(s.id, s.position_px);
  d.unassigned = static_cast<int>(located.unassigned.size());
  d.missing = static_cast<int>(located.missing.size());
  return d;
}

namespace {

// The same capture given twice (one file under two names, or a copy) is no new information, yet each copy would
// shrink the reported standard deviations by another sqrt(2): refused. Compared by pixels, whatever the encoding.
void RequireDistinctImages(const std::vector<BallImage>& balls) {
  for (size_t i = 0; i < balls.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      const cv::Mat& a = balls[i].image;
      const cv::Mat& b = balls[j].image;
      if (a.size() == b.size() && a.type() == b.type() && !a.empty() && cv::norm(a, b, cv::NORM_INF) == 0) {
        throw util::InputError(fmt::format("{}: the same image as {} (identical pixels): each ball must be its own "
                                           "capture",
                                           balls[i].name, balls[j].name));
      }
    }
  }
}

}  // namespace

DeviceCalibration CalibrateDevice(const std::vector<BallImage>& balls, const model::Device& nominal,
                                  const model::Config& config, const calib::DeviceFitOptions& options,
                                  const std::vector<calib::ViewObservations>& target_views) {
  for (const auto& b : balls) {
    if (!(b.radius_mm >= kMinBallRadiusMm && b.radius_mm <= kMaxBallRadiusMm)) {
      throw util::InputError(fmt::format("{}: radius {} mm is not a reference-ball radius ({}-{} mm)", b.name,
                                         b.radius_mm, kMinBallRadiusMm, kMaxBallRadiusMm));
    }
  }
  RequireDistinctImages(balls);
  DeviceCalibration out;
  std::vector<calib::BallView> views;
  for (const auto& b : balls) {
    out.detections.push_back(DetectBall(b, nominal, config.ideal_image));
    views.push_back(out.detections.back().view);
  }
  for (const auto& v : target_views) out.view_names.push_back(v.image_path);
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  out.fit = calib::FitDevice(nominal, config.topographer, design.targets, views, options, target_views);
  return out;
}

nlohmann::json DeviceCalibrationJson(const DeviceCalibration& c) {
  const auto& f = c.fit;
  nlohmann::json parameters = nlohmann::json::object();
  for (const auto& p : f.parameters) {
    parameters[p.name] = {{"value", p.value}, {"stddev", p.stddev}, {"nominal", p.nominal}};
  }
  nlohmann::json balls = nlohmann::json::array();
  for (size_t b = 0; b < f.ball_vertex_mm.size(); ++b) {
    const auto& d = c.detections[b];
    balls.push_back({{"image", d.view.name},
                     {"radius_mm", d.view.radius_mm},
                     {"spots_indexed", d.view.spots_px.size()},
                     {"unassigned", d.unassigned},
                     {"missing", d.missing},
                     {"rms_px", f.ball_rms_px[b]},
                     {"vertex_mm", {f.ball_vertex_mm[b].x(), f.ball_vertex_mm[b].y(), f.ball_vertex_mm[b].z()}},
                     {"vertex_stddev_mm", {f.ball_vertex_stddev_mm[b].x(), f.ball_vertex_stddev_mm[b].y(),
                                           f.ball_vertex_stddev_mm[b].z()}}});
  }
  nlohmann::json target_views = nlohmann::json::array();
  for (size_t v = 0; v < f.view_rms_px.size(); ++v) {
    target_views.push_back({{"image", c.view_names[v]}, {"corners", f.view_corners[v]}, {"rms_px", f.view_rms_px[v]}});
  }
  nlohmann::json names = nlohmann::json::array();
  for (const auto& p : f.parameters) names.push_back(p.name);
  nlohmann::json cov = nlohmann::json::array();
  for (int i = 0; i < f.covariance.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (int j = 0; j < f.covariance.cols(); ++j) row.push_back(f.covariance(i, j));
    cov.push_back(row);
  }
  nlohmann::json out = {
          {"method", fmt::format("reference balls{}: Ceres bundle adjustment of the screen pose, principal point, a, "
                                 "distortion and ball positions{} (docs/device.md)",
                                 c.view_names.empty() ? "" : " and target views",
                                 c.view_names.empty() ? "" : " and target poses")},
          {"parameters", parameters},
          {"covariance", {{"parameters", names}, {"matrix", cov}}},
          {"chi2_per_dof", f.chi2_per_dof},
          {"dof", f.dof},
          {"stddev_scale", f.stddev_scale},
          {"model_adequate", f.model_adequate},
          {"gauge", f.gauge},
          {"notes", f.notes},
          {"iterations", f.iterations},
          {"balls", balls}};
  if (!target_views.empty()) out["target_views"] = target_views;
  return out;
}

BallSpots SimulateBall(const model::Device& device, const model::Config& config, double radius_mm,
                       const Eigen::Vector3d& vertex_mm) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  model::Sphere ball;
  ball.radius_mm = radius_mm;
  ball.x0_mm = vertex_mm.x();
  ball.y0_mm = vertex_mm.y();
  ball.z0_mm = vertex_mm.z();
  const auto image = model::SynthesizeImage(ball, device, config.topographer, design.targets);
  BallSpots out;
  out.failures = design.failures;
  out.failures.insert(out.failures.end(), image.failures.begin(), image.failures.end());
  for (const auto& s : image.spots) out.spots_px.emplace_back(s.id, device.PixelOf(s.position_mm));
  return out;
}

}  // namespace topocal::pipeline
