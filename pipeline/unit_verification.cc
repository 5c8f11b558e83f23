#include "pipeline/unit_verification.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "correct/undistort_points.h"
#include "model/keratometry.h"
#include "model/null_screen.h"
#include "pipeline/detection_plane.h"
#include "pipeline/measure_spots.h"
#include "topo/power_map.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// The smallest and largest reference ball we accept: test spheres for corneal topographers span about
// 5-11 mm (ISO 19980 test surfaces cover the human range of 6-10 mm); outside that the null screen's spots leave
// the sensor or crowd together.
constexpr double kMinSphereRadiusMm = 5.0;
constexpr double kMaxSphereRadiusMm = 11.0;

StageResult Analyze(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
                    const model::Config& config, const model::BiconicParams& truth, const char* what) {
  StageResult r;
  try {
    r.analysis = topo::AnalyzeSpots(spots, targets, config, &truth);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", what, e.what()));
  }
  r.numbers = Summarize(r.analysis, static_cast<int>(spots.size()));
  return r;
}

// The uncertainty of one check, or none when there is nothing to propagate (no distortion parameter with a spread,
// e.g. all fixed: the record says so by leaving the uncertainty out). Anything else that stops the propagation — a
// covariance that does not match its names, too few samples, an analysis failing — is a computation error of this
// check: one line naming it (std::runtime_error), never a silently missing uncertainty.
std::optional<ClinicalUncertainty> Uncertainty(const std::vector<model::PlaneSpot>& detected,
                                               const UnitCalibration& unit, const model::TopographerCamera& camera,
                                               const model::Config& config, const CheckOptions& options,
                                               const char* what) {
  if (options.uncertainty.method == UncertaintySetting::Method::kNone) return std::nullopt;
  try {
    if (DistortionParametersToDraw(unit.covariance).empty()) return std::nullopt;
    return PropagateCalibrationUncertainty(detected, unit.camera, unit.covariance, camera, config,
                                           options.uncertainty.draws, options.seed, options.jobs);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", what, e.what()));
  }
}

DetectionPlaneModel OnDetectionPlane(const UnitCalibration& unit, const model::TopographerCamera& camera) {
  auto d = DetectionPlaneModelOf(unit.camera, camera);
  if (!d.ok) throw std::runtime_error("the calibration cannot be put on the detection plane: " + d.message);
  return d;
}

}  // namespace

ClinicalNumbers Summarize(const topo::Analysis& analysis, int spots) {
  ClinicalNumbers n;
  n.spots = spots;
  const auto& p = analysis.surface_fit.params;
  n.rx_mm = p.rx_mm;
  n.ry_mm = p.ry_mm;
  n.kx = p.kx;
  n.ky = p.ky;
  n.alpha_deg = p.alpha_deg;
  n.radius_mm = 0.5 * (p.rx_mm + p.ry_mm);
  n.central_axial_power_D = topo::MeanAxialPowerD(analysis.power, kCentralPowerRadiusMm);
  n.pv_tangential_D = analysis.power.pv_tangential_D;
  n.pv_axial_D = analysis.power.pv_axial_D;
  n.adequacy_ratio = analysis.reconstruction.adequacy_ratio;
  n.structured_residual_ratio = analysis.reconstruction.structured_residual_ratio;
  if (analysis.errors) {
    n.height_pv_um = analysis.errors->pv_um;
    n.height_rms_um = analysis.errors->rms_um;
  }
  return n;
}

model::Config WithSphere(const model::Config& config, double radius_mm) {
  model::Config c = config;
  c.cornea = model::BiconicParams{};
  c.cornea.rx_mm = c.cornea.ry_mm = radius_mm;
  c.cornea.kx = c.cornea.ky = 0.0;
  c.cornea.alpha_deg = 0.0;
  // Fitted as the sphere it is (topo/sphere_fit.h): centre and radius. The free-apex biconic is degenerate on a
  // sphere (its tilt and decentration are the same surface) and the paper's 6 parameters cannot follow a ball off
  // the axis or seen through a tilted screen. The record's k_x, k_y and alpha of a sphere are therefore 0 by
  // construction, not measured (docs/unit-record.md).
  c.reconstruction.biconic_fit = "sphere";
  return c;
}

SphereVerification DetectReferenceSphere(const cv::Mat& image, double radius_mm, const model::TopographerCamera& camera,
                                         const model::Config& config) {
  if (!(radius_mm >= kMinSphereRadiusMm && radius_mm <= kMaxSphereRadiusMm)) {
    throw util::InputError(fmt::format("sphere radius {} mm is outside [{}, {}] mm", radius_mm,
                                            kMinSphereRadiusMm, kMaxSphereRadiusMm));
  }
  if (image.cols != camera.width_px || image.rows != camera.height_px) {
    throw util::InputError(fmt::format("the image is {} x {} px but the camera is {} x {} px", image.cols,
                                            image.rows, camera.width_px, camera.height_px));
  }
  const model::Config sphere = WithSphere(config, radius_mm);
  SphereVerification v;
  // Detected and indexed once; the corrected stage undistorts the same spots.
  const auto raw = MeasureSpots(image, camera, sphere.ideal_image, std::nullopt);
  v.detected = raw.detected;
  v.spots_indexed = raw.indexed;
  v.spots_unassigned = raw.unassigned;
  v.spots_missing = raw.missing;
  return v;
}

SphereVerification VerifyOnReferenceSphere(const cv::Mat& image, double radius_mm, const UnitCalibration& unit,
                                           const model::TopographerCamera& camera, const model::Config& config,
                                           const CheckOptions& options) {
  return VerifyOnReferenceSphere(DetectReferenceSphere(image, radius_mm, camera, config), radius_mm, unit, camera,
                                 config, options);
}

SphereVerification VerifyOnReferenceSphere(SphereVerification v, double radius_mm, const UnitCalibration& unit,
                                           const model::TopographerCamera& camera, const model::Config& config,
                                           const CheckOptions& options) {
  if (!(radius_mm >= kMinSphereRadiusMm && radius_mm <= kMaxSphereRadiusMm)) {
    throw util::InputError(
        fmt::format("sphere radius {} mm is outside [{}, {}] mm", radius_mm, kMinSphereRadiusMm, kMaxSphereRadiusMm));
  }
  if (v.detected.empty()) throw util::InputError("no identified spots of the reference sphere");
  const model::Config sphere = WithSphere(config, radius_mm);
  const auto design = model::DesignNullScreen(sphere.ideal_image, sphere.topographer);
  const auto on_plane = OnDetectionPlane(unit, camera);
  const auto& distortion = on_plane.distortion;
  // The spots were located before the calibration was known: put them in the millimetres of the calibrated pixel
  // aspect (fx / fy), through the pixels they were found at.
  for (auto& s : v.detected) {
    s.position_mm = on_plane.camera.DetectionPlaneFromPixel(camera.PixelFromDetectionPlane(s.position_mm));
  }
  v.radius_true_mm = radius_mm;
  v.power_true_D = model::PowerFromCurvatureD(1.0 / radius_mm);  // Eq. 25
  v.undistort_failures = 0;
  const auto corrected = UndistortSpots(v.detected, distortion, &v.undistort_failures);
  v.uncorrected = Analyze(v.detected, design.targets, sphere, sphere.cornea, "reference sphere, uncorrected");
  v.corrected = Analyze(corrected, design.targets, sphere, sphere.cornea, "reference sphere, corrected");
  v.uncertainty = Uncertainty(v.detected, unit, camera, sphere, options, "reference sphere");
  return v;
}

SimulatedCornea SimulateThroughCalibratedCamera(const UnitCalibration& unit, const model::TopographerCamera& camera,
                                                const model::Config& config, const CheckOptions& options) {
  const auto distortion = OnDetectionPlane(unit, camera).distortion;
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto ideal =
      model::SynthesizeImage(model::Biconic{config.cornea}, model::Topographer{config.topographer}, design.targets);
  std::vector<Eigen::Vector2d> ideal_mm;
  for (const auto& s : ideal.spots) ideal_mm.push_back(s.position_mm);
  const auto distorted_mm = correct::DistortPoints(distortion, ideal_mm);

  SimulatedCornea out;
  out.truth = config.cornea;
  std::vector<model::PlaneSpot> distorted;
  std::vector<model::PlaneSpot> detected;
  for (size_t i = 0; i < ideal.spots.size(); ++i) {
    distorted.push_back({ideal.spots[i].id, distorted_mm[i]});
    detected.push_back({ideal.spots[i].id, distorted_mm[i]});
    out.max_displacement_um = std::max(out.max_displacement_um, (distorted_mm[i] - ideal_mm[i]).norm() * 1000.0);
  }
  const auto corrected = UndistortSpots(detected, distortion);
  out.uncorrected = Analyze(distorted, design.targets, config, config.cornea, "paper cornea, uncorrected");
  out.corrected = Analyze(corrected, design.targets, config, config.cornea, "paper cornea, corrected");
  out.uncertainty = Uncertainty(detected, unit, camera, config, options, "paper cornea");
  return out;
}

}  // namespace topocal::pipeline
