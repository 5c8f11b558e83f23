#pragma once
// A complete unit record (docs/unit-record.md) built in a temporary directory for the report tests: a real Seidel
// single-view calibration of seeded synthetic corners (calib::CalibrateSingleView, written with
// calib::WriteCalibrationFile), its residuals.csv, small PNG maps drawn with OpenCV, and a unit.json listing every
// file with its SHA-256. Tests mutate the JSON or the files to make each kind of bad record.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "calib/calibration_file.h"
#include "correct/undistort_points.h"
#include "model/config.h"
#include "model/null_screen.h"
#include "model/spots_csv.h"
#include "model/topographer_camera.h"
#include "pipeline/detection_plane.h"
#include "pipeline/unit_verification.h"
#include "report/unit_record_reader.h"
#include "report/unit_record_writer.h"
#include "tests/calib/synthetic_views.h"
#include "util/io.h"
#include "util/sha256.h"
#include "util/version.h"

namespace topocal::report::testing {

namespace fs = std::filesystem;
using nlohmann::json;

// The topographer camera of data/camera.json and the paper's Seidel sigma (Table IV) at the cornea position.
inline constexpr int kWidthPx = 4000, kHeightPx = 3000;
inline constexpr double kFocalMm = 5.2, kPitchUm = 1.12, kDistanceMm = 70, kSigmaPerMm2 = 6.3e-5;
inline constexpr double kCornerNoisePx = 0.05;  // gives a covariance (noise-free corners would make it ~0)
inline constexpr const char* kCreatedUtc = "2026-11-25T19:00:00Z";

// A fresh empty directory under the system temp dir, unique per test and process.
inline std::string FreshDir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::temp_directory_path() /
                       fmt::format("topocal_report_{}_{}_{}_{}", info ? info->test_suite_name() : "x",
                                   info ? info->name() : "x", name, ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

struct RecordFixture {
  std::string dir;
  json unit;
  calib::CalibrationResult calibration;

  std::string Path(const std::string& name) const { return (fs::path(dir) / name).string(); }
  // Rewrites unit.json from `unit` (after a test changed it).
  void WriteUnitJson() const { util::WriteFileAtomic(Path("unit.json"), unit.dump(2) + "\n"); }
  // Recomputes the `files` list (sorted, with digests) from the files on disk, then writes unit.json.
  void Seal() {
    std::vector<std::string> names;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      if (!e.is_regular_file()) continue;
      const std::string name = fs::relative(e.path(), dir).generic_string();
      if (name != "unit.json") names.push_back(name);
    }
    std::sort(names.begin(), names.end());
    unit["files"] = json::array();
    for (const std::string& n : names)
      unit["files"].push_back({{"name", n}, {"sha256", util::Sha256HexOfFile(Path(n))}});
    WriteUnitJson();
  }
};

inline calib::CalibrationResult FixtureCalibration() {
  model::CameraModel cam;
  cam.width_px = kWidthPx;
  cam.height_px = kHeightPx;
  cam.fx_px = cam.fy_px = kFocalMm / (kPitchUm * 1e-3);
  cam.cx_px = (kWidthPx - 1) / 2.0;
  cam.cy_px = (kHeightPx - 1) / 2.0;
  // sigma = k1 M_T^3 / f_mm^2 (model/distortion.h)
  cam.dist[0] = kSigmaPerMm2 * kFocalMm * kFocalMm / std::pow(calib::kPaperMagnification, 3);
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
  EXPECT_TRUE(result.ok()) << result.message;
  return result;
}

inline void WriteMapPng(const std::string& path, int seed) {
  cv::Mat img(90, 120, CV_8UC3);
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(2 * x), cv::saturate_cast<uchar>(2 * y + seed * 30),
                                          cv::saturate_cast<uchar>(255 - 2 * x));
    }
  }
  cv::circle(img, {60, 45}, 30, cv::Scalar(255, 255, 255), 2);
  ASSERT_TRUE(cv::imwrite(path, img)) << path;
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
    const auto camera = model::LoadTopographerCamera(std::string(TOPOCAL_SOURCE_DIR) + "/data/camera.json");
    pipeline::UnitCalibration unit;
    unit.camera = r.camera;
    unit.covariance.names.assign(std::begin(calib::kParameterNames), std::end(calib::kParameterNames));
    unit.covariance.matrix = r.covariance;
    unit.covariance.full = true;
    const pipeline::CheckOptions check{kFixtureDraws, 1, 0};
    FixtureChecks c;
    c.configuration = {{"design", json::parse(model::ConfigToJson(config))},
                       {"camera", json::parse(model::TopographerCameraToJson(camera))}};
    const auto on_plane = pipeline::DetectionPlaneModelOf(r.camera, camera);
    EXPECT_TRUE(on_plane.ok) << on_plane.message;
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
        {"uncertainty_samples", kFixtureDraws},
        {"seed", 1}}},
      {"inputs",
       {{{"role", "config"}, {"path", "data/paper.json"}, {"sha256", util::Sha256Hex("config")}},
        {{"role", "camera"}, {"path", "data/camera.json"}, {"sha256", util::Sha256Hex("camera")}},
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

inline json Uncertainty(double u_r, double u_k) {
  return {{"samples", 200},
          {"seed", 1},
          {"failed_samples", 0},
          {"drawn", {"k1"}},
          {"quantities",
           {{"rx_mm", {{"mean", 7.8001}, {"U", u_r}}},
            {"ry_mm", {{"mean", 7.7999}, {"U", u_r}}},
            {"kx", {{"mean", 0.0002}, {"U", u_k}}},
            {"ky", {{"mean", -0.0002}, {"U", u_k}}},
            {"alpha_deg", {{"mean", 0.0}, {"U", 0.5}}},
            {"pv_tangential_D", {{"mean", 0.03}, {"U", 0.01}}},
            {"pv_axial_D", {{"mean", 0.02}, {"U", 0.01}}}}}};
}

inline void UseHandPickedChecks(RecordFixture& f) {
  f.unit["verification"] = {{"image", "sphere.png"},
                            {"radius_true_mm", 7.8},
                            {"power_true_D", 337.5 / 7.8},
                            {"keratometric_index", 1.3375},
                            {"uncorrected", StageSphere(7.8, 0.004, 0.08)},
                            {"corrected", StageSphere(7.8, 0.0005, 0.0002)},
                            {"uncertainty", Uncertainty(0.002, 0.004)}};
  f.unit["paper_cornea"] = {
      {"truth", {{"rx_mm", 7.8}, {"ry_mm", 7.63}, {"kx", -0.43}, {"ky", -0.25}, {"alpha_deg", 17.0}}},
      {"uncorrected",
       {{"rx_mm", 7.79},
        {"ry_mm", 7.62},
        {"kx", -0.61},
        {"ky", -0.43},
        {"alpha_deg", 17.0},
        {"pv_tangential_D", 6.1},
        {"pv_axial_D", 3.2},
        {"height_pv_um", 3.5},
        {"height_rms_um", 0.8},
        {"adequacy_ratio", 3.4},
        {"structured_residual_ratio", 2.9}}},
      {"corrected",
       {{"rx_mm", 7.8001},
        {"ry_mm", 7.6299},
        {"kx", -0.4302},
        {"ky", -0.2501},
        {"alpha_deg", 17.0},
        {"pv_tangential_D", 5.6},
        {"pv_axial_D", 2.9},
        {"height_pv_um", 0.05},
        {"height_rms_um", 0.01},
        {"adequacy_ratio", 0.04},
        {"structured_residual_ratio", 0.03}}},
      {"uncertainty", Uncertainty(0.001, 0.003)}};
  f.WriteUnitJson();
}

// A complete, consistent record whose checks all pass the default limits.
inline RecordFixture MakeRecord(const std::string& dir) {
  RecordFixture f;
  f.dir = dir;
  fs::create_directories(dir);
  f.calibration = FixtureCalibration();
  const auto& r = f.calibration;
  calib::WriteCalibrationFile(f.Path("calibration.yaml"), r, {"data/target-topographer.yaml", {"views/v1.png"},
                                                              kCreatedUtc});
  util::WriteFileAtomic(f.Path("residuals.csv"), ResidualsCsv(r));
  util::WriteFileAtomic(f.Path("sphere_spots.csv"), model::SpotsCsv(ComputeChecks().sphere_spots));
  fs::create_directories(f.Path("maps"));
  int seed = 0;
  for (const char* name : {"sphere_uncorrected_axial_power", "sphere_corrected_axial_power",
                           "paper_uncorrected_axial_power", "paper_corrected_axial_power"}) {
    WriteMapPng(f.Path(fmt::format("maps/{}.png", name)), seed++);
  }
  f.unit = RecordBody(r);
  f.unit["format"] = "topocal-unit-record";
  f.unit["format_version"] = kUnitRecordFormatVersion;
  f.unit["tool_version"] = kVersion;
  f.Seal();
  return f;
}

}  // namespace topocal::report::testing
