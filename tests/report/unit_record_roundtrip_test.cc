// The unit record's round trip on real output: pipeline::CalibrateUnit computes a unit (calibration, reference
// sphere, paper cornea and the device stage from rendered ball images), report::WriteUnitRecord writes it,
// report::ReadUnitRecord reads it back, and every field the reader returns equals the value the workflow computed.
// Writer and reader spell the record's keys separately (report/unit_record_writer.cc, unit_record_reader.cc): a key
// renamed, dropped or rescaled on one side fails here, where the report tests' hand-built records cannot see it.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "calib/calibration_file.h"
#include "model/device.h"
#include "pipeline/device_calibration.h"
#include "pipeline/unit_workflow.h"
#include "report/record_check.h"
#include "report/unit_record_reader.h"
#include "report/unit_record_writer.h"
#include "tests/cli_harness.h"
#include "tests/report/record_fixture.h"
#include "tests/unit_fixture.h"
#include "topo/power_map.h"
#include "util/io.h"
#include "util/version.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;

// residuals.csv holds pixels with 6 decimals: a value comes back within half a unit of the last one.
constexpr double kCsvPixelTolerancePx = 5e-7;

// Every value the reader returned for a stage equals the computed one (the reader takes the keys of
// kSphereStageKeys, kPaperStageKeys, kDeviceStageKeys; the writer writes these and more). `extra`: keys the stage
// has beside the clinical numbers (the sphere's spots_indexed and errors).
void ExpectNumbers(const StageValues& read, const pipeline::ClinicalNumbers& n, const std::string& where,
                   const std::map<std::string, double>& extra = {}) {
  SCOPED_TRACE(where);
  // The key of each number, spelt here independently of the writer: the oracle the round trip is checked against.
  std::map<std::string, double> computed = {{"rx_mm", n.rx_mm},
                                            {"ry_mm", n.ry_mm},
                                            {"kx", n.kx},
                                            {"ky", n.ky},
                                            {"alpha_deg", n.alpha_deg},
                                            {"radius_mm", n.radius_mm},
                                            {"central_axial_power_D", n.central_axial_power_D},
                                            {"pv_tangential_D", n.pv_tangential_D},
                                            {"pv_axial_D", n.pv_axial_D},
                                            {"adequacy_ratio", n.adequacy_ratio},
                                            {"structured_residual_ratio", n.structured_residual_ratio}};
  for (const auto& [key, value] : {std::pair{"height_pv_um", n.height_pv_um}, std::pair{"height_rms_um", n.height_rms_um}}) {
    if (value) computed[key] = *value;
  }
  computed.insert(extra.begin(), extra.end());
  ASSERT_FALSE(read.empty());
  for (const auto& [key, value] : read) {
    ASSERT_TRUE(computed.count(key)) << key << ": read but not computed";
    EXPECT_EQ(value, computed.at(key)) << key;
  }
}

void ExpectUncertainty(const std::optional<UncertaintyBlock>& read,
                       const std::optional<pipeline::ClinicalUncertainty>& u, const pipeline::CheckOptions& check) {
  ASSERT_EQ(read.has_value(), u.has_value());
  if (!u) return;
  EXPECT_EQ(read->linear, u->linear);
  EXPECT_EQ(read->samples, u->samples);
  EXPECT_EQ(read->seed, static_cast<int>(check.seed));
  EXPECT_EQ(read->failed_samples, u->failed_samples);
  EXPECT_EQ(read->drawn, u->drawn);
  ASSERT_FALSE(read->quantities.empty());
  for (const auto& [name, q] : read->quantities) {
    ASSERT_TRUE(u->quantities.count(name)) << name << ": read but not computed";
    EXPECT_EQ(q.mean, u->quantities.at(name).mean) << name;
    EXPECT_EQ(q.U, u->quantities.at(name).expanded_k2) << name;
  }
}

void ExpectThreeWay(const std::map<std::string, StageValues>& read, const pipeline::ThreeWay& t,
                    const std::string& where) {
  ASSERT_EQ(read.size(), 3u) << where;
  ExpectNumbers(read.at("uncorrected"), t.uncorrected.numbers, where + ".uncorrected");
  ExpectNumbers(read.at("lens_only"), t.lens_only.numbers, where + ".lens_only");
  ExpectNumbers(read.at("device"), t.device.numbers, where + ".device");
}

TEST(UnitRecordRoundTrip, EveryFieldTheWorkflowComputedIsReadBackUnchanged) {
  const std::string in = testing_cli::UnitInputsDir();
  const std::string dir = testing::FreshDir("roundtrip");
  // The device stage's inputs: three reference balls and a held-out one through an assembled (tilted) device.
  const std::string device_json = dir + "/unit-device.json";
  util::WriteFileAtomic(device_json, R"({"format": "topocal-device", "format_version": 1,
    "camera": {"pixel_pitch_um": 1.12, "width_px": 1120, "height_px": 1120, "principal_point_px": [559.5, 559.5],
               "a_mm": 5.2},
    "distortion": {"model": "seidel", "sigma_per_mm2": 6.3e-5},
    "screen_pose": {"rx_deg": 0.8, "ry_deg": -0.5, "rz_deg": 0.3, "tx_mm": 0.1, "ty_mm": -0.05, "tz_mm": 0.3}})");
  pipeline::UnitRequest r;
  for (const auto& [radius, x, y, z] :
       {std::tuple{"6.5", "0.12", "-0.20", "0.00"}, std::tuple{"7.8", "-0.25", "0.10", "-0.15"},
        std::tuple{"9.0", "0.20", "0.22", "0.10"}, std::tuple{"7.8", "0.10", "0.05", "0.00"}}) {
    const std::string png = fmt::format("{}/ball-{}-{}.png", dir, radius, x);
    const auto b = testing_cli::RunTopocal(fmt::format(
        "render-spots --config {}/data/paper.json --device {} --sphere-radius-mm {} --ball-at {} {} {} --out {}",
        TOPOCAL_SOURCE_DIR, device_json, radius, x, y, z, png));
    ASSERT_EQ(b.exit_code, 0) << b.output;
    if (std::string(x) == "0.10") {
      r.reference_sphere = png;  // held out
    } else {
      r.balls.push_back(png);
      r.ball_radii_mm.push_back(std::stod(radius));
    }
  }
  r.serial = "RT-0001";
  r.target = in + "/target.yaml";
  r.images = {in + "/view.png"};
  r.config = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
  r.device = in + "/device.json";
  r.sphere_radius_mm = 7.8;
  r.seed = 3;
  r.out = dir + "/RT-0001";

  std::vector<std::string> log;
  const pipeline::UnitResult u = pipeline::CalibrateUnit(r, [&](const std::string& line) { log.push_back(line); });
  ASSERT_TRUE(u.sphere && u.device && u.device->held_out);
  WriteUnitRecord(u);
  const UnitRecord rec = ReadUnitRecord(r.out);

  // Identity and settings.
  EXPECT_EQ(rec.serial, r.serial);
  EXPECT_EQ(rec.created_utc, u.created_utc);
  EXPECT_EQ(rec.tool_version, kVersion);
  EXPECT_EQ(rec.format_version, kUnitRecordFormatVersion);
  EXPECT_EQ(rec.settings_model, r.model);
  EXPECT_EQ(rec.settings_single_view, u.calibration.single_view);
  EXPECT_EQ(rec.settings_fit_centre, r.fit_centre);
  ASSERT_TRUE(rec.settings_sphere_radius_mm);
  EXPECT_EQ(*rec.settings_sphere_radius_mm, r.sphere_radius_mm);
  EXPECT_EQ(rec.settings_uncertainty.method, pipeline::UncertaintySetting::Method::kLinear);  // the default
  EXPECT_EQ(rec.settings_uncertainty.draws, r.uncertainty.draws);
  EXPECT_EQ(rec.settings_seed, static_cast<int>(r.seed));

  // Provenance: every input with its digest, in order.
  ASSERT_EQ(rec.inputs.size(), u.inputs.size());
  EXPECT_EQ(u.inputs.size(), 4u + r.images.size() + r.balls.size());  // config camera target sphere + images + balls
  for (size_t i = 0; i < u.inputs.size(); ++i) {
    EXPECT_EQ(rec.inputs[i].role, u.inputs[i].role) << i;
    EXPECT_EQ(rec.inputs[i].path, u.inputs[i].path) << i;
    EXPECT_EQ(rec.inputs[i].sha256, u.inputs[i].sha256) << i;
  }
  // Files: exactly what is in the directory besides unit.json (the reader verified every digest).
  std::set<std::string> on_disk, listed;
  for (const auto& e : fs::recursive_directory_iterator(r.out)) {
    if (e.is_regular_file()) on_disk.insert(fs::relative(e.path(), r.out).generic_string());
  }
  on_disk.erase("unit.json");
  for (const auto& f : rec.files) listed.insert(f.name);
  EXPECT_EQ(listed, on_disk);
  EXPECT_TRUE(listed.count("device.json"));

  // Camera.
  EXPECT_EQ(rec.camera_pixel_pitch_um, u.camera.pixel_pitch_um);
  EXPECT_EQ(rec.camera_width_px, u.camera.width_px);
  EXPECT_EQ(rec.camera_height_px, u.camera.height_px);
  EXPECT_EQ(rec.camera_a_mm, u.camera.a_mm);

  // Calibration block.
  const auto& cal = u.calibration.result;
  EXPECT_EQ(rec.calibration_model, calib::ToString(cal.model));
  EXPECT_EQ(rec.calibration_single_view, cal.single_view);
  EXPECT_EQ(rec.calibration_width_px, cal.camera.width_px);
  EXPECT_EQ(rec.calibration_height_px, cal.camera.height_px);
  EXPECT_EQ(rec.calibration_rms_px, cal.rms_px);
  EXPECT_EQ(rec.corners_used, cal.corners_used);
  EXPECT_EQ(rec.outliers, static_cast<int>(cal.outliers.size()));
  ASSERT_EQ(rec.parameters.size(), cal.parameters.size());
  for (size_t i = 0; i < cal.parameters.size(); ++i) {
    EXPECT_EQ(rec.parameters[i].name, cal.parameters[i].name);
    EXPECT_EQ(rec.parameters[i].value, cal.parameters[i].value) << cal.parameters[i].name;
    EXPECT_EQ(rec.parameters[i].stddev, cal.parameters[i].stddev) << cal.parameters[i].name;
    EXPECT_EQ(rec.parameters[i].fixed, cal.parameters[i].fixed) << cal.parameters[i].name;
  }
  ASSERT_TRUE(cal.seidel && rec.seidel_sigma_per_mm2 && rec.seidel_sigma_stddev_per_mm2 && rec.seidel_magnification &&
              rec.seidel_focal_mm);
  EXPECT_EQ(*rec.seidel_sigma_per_mm2, cal.seidel->sigma_per_mm2);
  EXPECT_EQ(*rec.seidel_sigma_stddev_per_mm2, cal.seidel->sigma_stddev_per_mm2);
  EXPECT_EQ(*rec.seidel_magnification, cal.seidel->magnification);
  EXPECT_EQ(*rec.seidel_focal_mm, cal.seidel->focal_mm);
  ASSERT_EQ(rec.views.size(), cal.views_used.size());
  for (size_t v = 0; v < cal.views_used.size(); ++v) {
    EXPECT_EQ(rec.views[v].image, u.calibration.view_paths[static_cast<size_t>(cal.views_used[v])]);
    EXPECT_EQ(rec.views[v].rms_px, cal.per_view_rms_px[v]);
    EXPECT_EQ(rec.views[v].corners, cal.corners_used);  // one view: all its inlier corners
  }
  ASSERT_TRUE(rec.field_radius_px);
  EXPECT_EQ(*rec.field_radius_px, u.field.field_radius_mm / u.camera.PitchMm());

  // Reference sphere.
  ASSERT_TRUE(rec.verification);
  const auto& s = *u.sphere;
  const auto& v = *rec.verification;
  EXPECT_EQ(v.image, r.reference_sphere);
  EXPECT_EQ(v.radius_true_mm, s.radius_true_mm);
  EXPECT_EQ(v.power_true_D, s.power_true_D);
  EXPECT_EQ(v.keratometric_index, topo::kKeratometricIndex);
  for (const auto& [read, stage, name] : {std::tuple{&v.uncorrected, &s.uncorrected, "uncorrected"},
                                          std::tuple{&v.corrected, &s.corrected, "corrected"}}) {
    ExpectNumbers(*read, stage->numbers, std::string("verification.") + name,
                  {{"spots_indexed", s.spots_indexed},
                   {"radius_error_mm", s.RadiusErrorMm(*stage)},
                   {"power_error_D", s.PowerErrorD(*stage)}});
  }
  ExpectUncertainty(v.uncertainty, s.uncertainty, u.check);
  EXPECT_FALSE(v.repeatability);  // one sphere image: the workflow writes none
  // sphere_spots.csv: the spots the check used, to the last bit (the report recomputes the check from them).
  ASSERT_EQ(v.detected.size(), s.detected.size());
  ASSERT_FALSE(s.detected.empty());
  for (std::size_t i = 0; i < s.detected.size(); ++i) {
    EXPECT_EQ(v.detected[i].id, s.detected[i].id) << i;
    EXPECT_EQ(v.detected[i].position_mm.x(), s.detected[i].position_mm.x()) << i;
    EXPECT_EQ(v.detected[i].position_mm.y(), s.detected[i].position_mm.y()) << i;
  }
  EXPECT_EQ(v.spots_unassigned, s.spots_unassigned);
  EXPECT_EQ(v.spots_missing, s.spots_missing);

  // Paper cornea.
  const auto& t = u.paper.truth;
  EXPECT_EQ(rec.paper.truth.at("rx_mm"), t.rx_mm);
  EXPECT_EQ(rec.paper.truth.at("ry_mm"), t.ry_mm);
  EXPECT_EQ(rec.paper.truth.at("kx"), t.kx);
  EXPECT_EQ(rec.paper.truth.at("ky"), t.ky);
  EXPECT_EQ(rec.paper.truth.at("alpha_deg"), t.alpha_deg);
  ExpectNumbers(rec.paper.uncorrected, u.paper.uncorrected.numbers, "paper_cornea.uncorrected");
  ExpectNumbers(rec.paper.corrected, u.paper.corrected.numbers, "paper_cornea.corrected");
  ExpectUncertainty(rec.paper.uncertainty, u.paper.uncertainty, u.check);

  // Device stage: device.json holds the fitted device and its calibration summary; the three-way measurements.
  ASSERT_TRUE(rec.device);
  const auto& d = *u.device;
  EXPECT_EQ(model::DeviceToJson(rec.device->file.device), model::DeviceToJson(d.calibration.fit.device));
  EXPECT_EQ(rec.device->file.calibration, pipeline::DeviceCalibrationJson(d.calibration));
  ExpectThreeWay(rec.device->paper, d.paper, "device.paper_cornea");
  ExpectThreeWay(rec.device->held_out, d.held_out->stages, "device.held_out_ball");
  EXPECT_EQ(rec.device->held_out_radius_true_mm, d.held_out->radius_true_mm);
  EXPECT_EQ(rec.device->held_out_power_true_D, d.held_out->power_true_D);

  // The report's recomputation of the checks from the record's files agrees with what the workflow wrote, on one
  // thread and on two (the draws are seeded per draw).
  EXPECT_NO_THROW(RecomputeRecordNumbers(rec, {1}));
  EXPECT_NO_THROW(RecomputeRecordNumbers(rec, {2}));

  // calibration.yaml: the calibrated camera (OpenCV writes 17 significant digits).
  const auto& cam = rec.calibration.camera;
  EXPECT_EQ(cam.width_px, cal.camera.width_px);
  EXPECT_EQ(cam.height_px, cal.camera.height_px);
  EXPECT_DOUBLE_EQ(cam.fx_px, cal.camera.fx_px);
  EXPECT_DOUBLE_EQ(cam.fy_px, cal.camera.fy_px);
  EXPECT_DOUBLE_EQ(cam.cx_px, cal.camera.cx_px);
  EXPECT_DOUBLE_EQ(cam.cy_px, cal.camera.cy_px);
  for (size_t i = 0; i < cam.dist.size(); ++i) EXPECT_DOUBLE_EQ(cam.dist[i], cal.camera.dist[i]) << i;
  EXPECT_EQ(rec.calibration.date, u.created_utc);
  EXPECT_EQ(rec.calibration.target, r.target);

  // residuals.csv: every corner, in order.
  ASSERT_EQ(rec.residuals.size(), cal.residuals.size());
  for (size_t i = 0; i < cal.residuals.size(); ++i) {
    const auto& a = rec.residuals[i];
    const auto& b = cal.residuals[i];
    EXPECT_EQ(a.view, b.view);
    EXPECT_EQ(a.image, u.calibration.view_paths[static_cast<size_t>(b.view)]);
    EXPECT_EQ(a.corner_id, b.corner_id);
    EXPECT_NEAR(a.x_px, b.observed_px.x(), kCsvPixelTolerancePx);
    EXPECT_NEAR(a.y_px, b.observed_px.y(), kCsvPixelTolerancePx);
    EXPECT_NEAR(a.dx_px, b.residual_px.x(), kCsvPixelTolerancePx);
    EXPECT_NEAR(a.dy_px, b.residual_px.y(), kCsvPixelTolerancePx);
    EXPECT_EQ(a.outlier, b.outlier);
  }

  // maps/: both stages of both cases, four maps each (axial, tangential, elevation, height difference), all PNGs.
  std::set<std::string> maps;
  for (const auto& [name, bytes] : rec.map_png) {
    maps.insert(name);
    const std::vector<uchar> buf(bytes.begin(), bytes.end());
    EXPECT_FALSE(cv::imdecode(buf, cv::IMREAD_UNCHANGED).empty()) << name;
  }
  std::set<std::string> expected;
  for (const char* c : {"sphere_uncorrected_", "sphere_corrected_", "paper_uncorrected_", "paper_corrected_"}) {
    for (const char* m : {"axial_power", "tangential_power", "elevation", "height_difference"}) {
      expected.insert(std::string(c) + m + ".png");
    }
  }
  EXPECT_EQ(maps, expected);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace topocal::report
