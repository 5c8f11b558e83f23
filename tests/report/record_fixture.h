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
#include "tests/report/record_body.h"
#include "tests/calib/synthetic_views.h"
#include "util/io.h"
#include "util/sha256.h"
#include "util/version.h"

namespace topocal::report::testing {

namespace fs = std::filesystem;
using nlohmann::json;


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


inline json Uncertainty(double u_r, double u_k) {
  return {{"method", "monte-carlo"},
          {"samples", 200},
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
