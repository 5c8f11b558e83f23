#pragma once
// The body of a complete, consistent unit record (docs/unit-record.md), without GoogleTest: a real Seidel single-view
// calibration of seeded synthetic corners, its residuals.csv, and the record's two checks computed for real as
// `topocal unit calibrate` computes them. Shared by the report tests (record_fixture.h) and the generated production
// line (fleet_line.h, which bench/fleet_generate.cc also writes). Failures throw std::runtime_error.
#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "calib/calibration_file.h"
#include "correct/undistort_points.h"
#include "model/config.h"
#include "model/null_screen.h"
#include "model/spots_csv.h"
#include "model/device.h"
#include "model/topographer_camera.h"
#include "pipeline/detection_plane.h"
#include "pipeline/unit_verification.h"
#include "report/unit_record_writer.h"
#include "tests/calib/synthetic_views.h"
#include "util/sha256.h"

namespace topocal::report::testing {

using nlohmann::json;

// The topographer camera of data/device.json and the paper's Seidel sigma (Table IV) at the cornea position.
inline constexpr int kWidthPx = 4000, kHeightPx = 3000;
inline constexpr double kFocalMm = 5.2, kPitchUm = 1.12, kDistanceMm = 70, kSigmaPerMm2 = 6.3e-5;
inline constexpr double kCornerNoisePx = 0.05;  // gives a covariance (noise-free corners would make it ~0)
inline constexpr const char* kCreatedUtc = "2026-11-25T19:00:00Z";

inline calib::CalibrationResult FixtureCalibration() {
  model::CameraModel cam;
  cam.width_px = kWidthPx;
  cam.height_px = kHeightPx;
  cam.fx_px = cam.fy_px = kFocalMm / (kPitchUm * 1e-3);
  cam.cx_px = (kWidthPx - 1) / 2.0;
  cam.cy_px = (kHeightPx - 1) / 2.0;
  // sigma = k1 M_T^3 / f_mm^2 (model/distortion.h)
  cam.dist[0] = kSigmaPerMm2 * kFocalMm * kFocalMm / std::pow(model::kPaperMagnification, 3);
  calib::testing::GridTarget grid{13, 13, 0.9};
  std::mt19937 rng(7);
  const auto pose = calib::testing::MakePose(2, -3, 1, {0.3, -0.2, kDistanceMm}, grid);
  const auto view = calib::testing::ProjectGrid(cam, pose, grid, kCornerNoisePx, rng);
  calib::CalibrationOptions o;
  o.model = calib::DistortionModelKind::kSeidel;
  o.focal_mm = kFocalMm;
  o.pixel_pitch_um = kPitchUm;
  o.distance_mm = kDistanceMm;
  auto result = calib::CalibrateSingleView(view, o);
  if (!result.ok()) throw std::runtime_error("the fixture calibration failed: " + result.message);
  return result;
}

inline std::string ResidualsCsv(const calib::CalibrationResult& r) {
  std::string csv = "view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier\n";
  for (const auto& c : r.residuals) {
    csv += fmt::format("{},views/v1.png,{},{:.6f},{:.6f},{:.6f},{:.6f},{}\n", c.view, c.corner_id, c.observed_px.x(),
                       c.observed_px.y(), c.residual_px.x(), c.residual_px.y(), c.outlier ? 1 : 0);
  }
  return csv;
}

// The record's two checks computed for real, as `topocal unit calibrate` does (pipeline/unit_verification.h), for
// FixtureCalibration() with the bundled design and camera: the reference sphere's spots synthesised through the
// calibrated distortion instead of detected in a rendered image. Computed once per process.
inline constexpr int kFixtureDraws = 8;
struct FixtureChecks {
  json configuration, verification, paper_cornea;
  std::vector<model::ImageSpot> sphere_spots;  // as the camera saw them (sphere_spots.csv)
};
inline const FixtureChecks& ComputeChecks() {
  static const FixtureChecks checks = [] {
    const calib::CalibrationResult r = FixtureCalibration();
    const auto config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
    const auto camera = model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json").device.camera;
    pipeline::UnitCalibration unit;
    unit.camera = r.camera;
    unit.covariance.names = calib::CameraParameterNames(r.model);
    unit.covariance.matrix = r.covariance;
    unit.covariance.full = true;
    const pipeline::CheckOptions check{{pipeline::UncertaintySetting::Method::kMonteCarlo, kFixtureDraws}, 1, 0};
    FixtureChecks c;
    c.configuration = {{"design", json::parse(model::ConfigToJson(config))},
                       {"camera", json::parse(model::TopographerCameraToJson(camera))}};
    const auto on_plane = pipeline::DetectionPlaneModelOf(r.camera, camera);
    if (!on_plane.ok) throw std::runtime_error("the fixture's detection-plane model: " + on_plane.message);
    const std::optional<model::Distortion> distortion =
        on_plane.ok ? std::optional<model::Distortion>(on_plane.distortion) : std::nullopt;
    const model::Config sphere = pipeline::WithSphere(config, 7.8);
    const auto design = model::DesignNullScreen(sphere.ideal_image, sphere.topographer);
    const auto ideal =
        model::SynthesizeImage(model::Biconic{sphere.cornea}, model::Topographer{sphere.topographer}, design.targets);
    std::vector<Eigen::Vector2d> ideal_mm;
    for (const auto& spot : ideal.spots) ideal_mm.push_back(spot.position_mm);
    const auto seen_mm = correct::DistortPoints(*distortion, ideal_mm);
    pipeline::SphereVerification v;
    for (std::size_t i = 0; i < ideal.spots.size(); ++i) {
      v.detected.push_back({ideal.spots[i].id, seen_mm[i]});
      c.sphere_spots.push_back({ideal.spots[i].id, seen_mm[i], Eigen::Vector3d::Zero()});
    }
    v.spots_indexed = static_cast<int>(v.detected.size());
    v = pipeline::VerifyOnReferenceSphere(std::move(v), 7.8, unit, camera, config, check);
    c.verification = VerificationJson(v, "sphere.png", check);
    c.paper_cornea = PaperCorneaJson(pipeline::SimulateThroughCalibratedCamera(unit, camera, config, check), check);
    return c;
  }();
  return checks;
}

// unit.json of a record calibrated with `r` whose checks all pass the default limits, without the keys the writer
// adds (format, versions, files).
inline json RecordBody(const calib::CalibrationResult& r, const std::string& serial = "SN-TEST-0001",
                       const std::string& created_utc = kCreatedUtc) {
  const FixtureChecks& checks = ComputeChecks();  // of FixtureCalibration(), whatever `r` is
  json params = json::array();
  for (const auto& p : r.parameters) {
    params.push_back({{"name", p.name}, {"value", p.value}, {"stddev", p.stddev}, {"fixed", p.fixed}});
  }
  const std::string zero_hash(64, '0');
  return {
      {"serial", serial},
      {"created_utc", created_utc},
      {"settings",
       {{"model", "seidel"},
        {"single_view", true},
        {"fit_centre", false},
        {"sphere_radius_mm", 7.8},
        {"uncertainty", "monte-carlo"},
        {"uncertainty_samples", kFixtureDraws},
        {"seed", 1}}},
      {"inputs",
       {{{"role", "config"}, {"path", "data/paper.json"}, {"sha256", util::Sha256Hex("config")}},
        {{"role", "device"}, {"path", "data/device.json"}, {"sha256", util::Sha256Hex("device")}},
        {{"role", "target"}, {"path", "data/target-topographer.yaml"}, {"sha256", util::Sha256Hex("target")}},
        {{"role", "image"}, {"path", "views/v1.png"}, {"sha256", util::Sha256Hex("v1")}},
        {{"role", "reference_sphere"}, {"path", "sphere.png"}, {"sha256", zero_hash}}}},
      {"camera",
       {{"pixel_pitch_um", kPitchUm},
        {"width_px", kWidthPx},
        {"height_px", kHeightPx},
        {"a_mm", kFocalMm},
        {"principal_point_px", {(kWidthPx - 1) / 2.0, (kHeightPx - 1) / 2.0}}}},
      {"calibration",
       {{"model", "seidel"},
        {"single_view", true},
        {"image_width_px", kWidthPx},
        {"image_height_px", kHeightPx},
        {"rms_px", r.rms_px},
        {"corners_used", r.corners_used},
        {"outliers", static_cast<int>(r.outliers.size())},
        {"parameters", params},
        {"seidel",
         {{"sigma_per_mm2", r.seidel->sigma_per_mm2},
          {"sigma_stddev_per_mm2", r.seidel->sigma_stddev_per_mm2},
          {"magnification", r.seidel->magnification},
          {"focal_mm", r.seidel->focal_mm}}},
        {"views", {{{"image", "views/v1.png"}, {"rms_px", r.per_view_rms_px.at(0)}, {"corners", r.corners_used}}}},
        {"distortion_field",
         {{"max_displacement_px", 12.3}, {"max_displacement_um", 13.8}, {"field_radius_px", 560}}}}},
      // The checks as the unit workflow computes them for this calibration (report/record_check.h recomputes them).
      {"configuration", checks.configuration},
      {"verification", checks.verification},
      {"paper_cornea", checks.paper_cornea},
  };
}

// Hand-picked check numbers for the tests of the decision rule, the budget and the page (report/acceptance.h,
// html_report.h), which are functions of the numbers alone: round values whose verdicts and budgets can be
// computed by hand. Such a record no longer matches its own files, so `topocal report` (which recomputes them,
// report/record_check.h) refuses it; the library functions under test do not recompute.
inline json StageSphere(double radius_mm, double dr_mm, double dk) {
  const double r = radius_mm + dr_mm;
  const double power = 337.5 / r;
  return {{"spots_indexed", 624},
          {"rx_mm", r + 1e-4},
          {"ry_mm", r - 1e-4},
          {"kx", dk},
          {"ky", -dk},
          {"alpha_deg", 0.0},
          {"radius_mm", r},
          {"radius_error_mm", dr_mm},
          {"central_axial_power_D", power},
          {"power_error_D", power - 337.5 / radius_mm},
          {"pv_tangential_D", 0.02 + 10 * std::abs(dk)},
          {"pv_axial_D", 0.01 + 5 * std::abs(dk)},
          {"adequacy_ratio", 0.5 + 100 * std::abs(dk)},
          {"structured_residual_ratio", 0.1 + 20 * std::abs(dk)}};
}

}  // namespace topocal::report::testing
