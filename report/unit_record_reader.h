#pragma once
// Reading a unit record (docs/unit-record.md) for the QA report: the directory `topocal unit calibrate` writes,
// checked before a single number of it is shown.
//
//   units/SN/unit.json          format, format_version, tool_version (== topocal::kVersion), identity, results
//   units/SN/calibration.yaml   calib::LoadCalibrationFile (strict)
//   units/SN/residuals.csv      view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier
//   units/SN/maps/*.png         embedded as they are
//
// Every file listed in unit.json's `files` must exist with the listed SHA-256, and calibration.yaml and
// residuals.csv must be among them: a record that is incomplete or was changed after it was written is refused.
// Every error is a util::InputError with one line "PATH: KEY: problem".
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibration_file.h"
#include "model/config.h"
#include "model/device.h"
#include "model/spots_csv.h"
#include "model/topographer_camera.h"
#include "pipeline/uncertainty.h"

namespace topocal::report {

// Versions of the record this reader understands.
inline constexpr const char* kUnitRecordFormat = "topocal-unit-record";
inline constexpr int kUnitRecordFormatVersion = 4;  // 2: sphere_spots.csv, uncertainty may be null; 3: adequacy;
                                                    // 4: settings.uncertainty, the uncertainty blocks' method
inline constexpr const char* kSphereSpotsCsv = "sphere_spots.csv";

struct InputFile {
  std::string role, path, sha256;
};

struct RecordFile {
  std::string name;    // relative to the record directory
  std::string sha256;  // as listed, and verified against the file
};

struct CalibrationParameter {
  std::string name;
  double value = 0;
  double stddev = 0;
  bool fixed = false;
};

struct ViewRms {
  std::string image;
  double rms_px = 0;
  int corners = 0;
};

// One row of residuals.csv: the corner where it was observed and predicted - observed.
struct CornerResidualRow {
  int view = 0;
  std::string image;
  int corner_id = 0;
  double x_px = 0, y_px = 0, dx_px = 0, dy_px = 0;
  bool outlier = false;
};

// value +- U (k = 2) of one clinical number from the calibration's uncertainty (mean: the calibration's own value with
// linear propagation, the draws' mean with Monte Carlo).
struct ExpandedUncertainty {
  double mean = 0;
  double U = 0;
};

struct UncertaintyBlock {
  bool linear = false;  // "method": "linear" (else "monte-carlo")
  int samples = 0;      // linear: eigen-directions; Monte Carlo: draws that reconstructed
  int seed = 0;
  int failed_samples = 0;
  std::vector<std::string> drawn;
  std::map<std::string, ExpandedUncertainty> quantities;  // rx_mm, ry_mm, kx, ky, alpha_deg, pv_*_D
};

// The numbers of one stage (uncorrected or corrected) of a case, by key as in unit.json (rx_mm, kx, ...).
using StageValues = std::map<std::string, double>;

// Repeated measurements of the reference sphere (optional unit.json key verification.repeatability: arrays
// "radius_mm" and "central_axial_power_D" of the same length >= 2, one entry per image): the sample standard
// deviations are the repeatability terms of the uncertainty budget (report/acceptance.h).
struct SphereRepeatability {
  int images = 0;
  double radius_stddev_mm = 0, power_stddev_D = 0;
};

struct SphereVerification {
  std::string image;
  int spots_unassigned = 0, spots_missing = 0;
  // sphere_spots.csv: the identified spots as the camera saw them (detection-plane mm, distorted), from which the
  // report recomputes the check (report/record_check.h); empty when the record does not list the file.
  std::vector<model::PlaneSpot> detected;
  double radius_true_mm = 0, power_true_D = 0, keratometric_index = 0;
  StageValues uncorrected, corrected;
  std::optional<UncertaintyBlock> uncertainty;
  std::optional<SphereRepeatability> repeatability;
};

struct PaperCornea {
  StageValues truth, uncorrected, corrected;
  std::optional<UncertaintyBlock> uncertainty;
};

// The keys each stage must hold (docs/unit-record.md).
inline constexpr const char* kSphereStageKeys[] = {
    "spots_indexed", "rx_mm", "ry_mm", "kx", "ky", "alpha_deg", "radius_mm", "radius_error_mm",
    "central_axial_power_D",  "power_error_D", "pv_tangential_D", "pv_axial_D", "adequacy_ratio",
    "structured_residual_ratio"};
inline constexpr const char* kPaperStageKeys[] = {
    "rx_mm",        "ry_mm",         "kx",             "ky",  "alpha_deg", "pv_tangential_D", "pv_axial_D",
    "height_pv_um", "height_rms_um", "adequacy_ratio", "structured_residual_ratio"};
inline constexpr const char* kPaperTruthKeys[] = {"rx_mm", "ry_mm", "kx", "ky", "alpha_deg"};

// The device stage of a record (docs/unit-record.md): the calibrated device as device.json holds it (read
// and checked like any record file), and the three-way measurements of the held-out ball and the paper cornea.
inline constexpr const char* kDeviceStageKeys[] = {"rx_mm", "ry_mm", "kx", "ky", "radius_mm", "central_axial_power_D",
                                                   "pv_tangential_D", "pv_axial_D"};
inline constexpr const char* kThreeWayStages[] = {"uncorrected", "lens_only", "device"};
struct DeviceStageRecord {
  model::DeviceFile file;                          // device.json
  std::map<std::string, StageValues> paper;        // by kThreeWayStages
  std::map<std::string, StageValues> held_out;     // empty without a held-out ball
  double held_out_radius_true_mm = 0, held_out_power_true_D = 0;
};

struct UnitRecord {
  std::string directory;
  std::string unit_json_path;
  std::string unit_json_sha256;
  // SHA-256 of unit.json's content: the parsed document written back compactly with its keys sorted, so that the
  // same record re-indented or with its keys reordered has the same content digest (the fleet database's identity).
  std::string unit_json_content_sha256;

  std::string serial, tool_version, created_utc;
  std::string tool_commit;  // the git commit of the topocal that wrote it (util/build_info.h); empty in older records
  int format_version = 0;

  // settings
  std::string settings_model;
  bool settings_single_view = false, settings_fit_centre = false;
  std::optional<double> settings_sphere_radius_mm;
  pipeline::UncertaintySetting settings_uncertainty;  // settings.uncertainty and uncertainty_samples
  int settings_seed = 0;

  std::vector<InputFile> inputs;
  std::vector<RecordFile> files;

  // camera
  double camera_pixel_pitch_um = 0, camera_a_mm = 0;
  int camera_width_px = 0, camera_height_px = 0;

  // calibration block of unit.json
  std::string calibration_model;
  bool calibration_single_view = false;
  int calibration_width_px = 0, calibration_height_px = 0;
  double calibration_rms_px = 0;
  int corners_used = 0, outliers = 0;
  std::vector<CalibrationParameter> parameters;
  std::optional<double> seidel_sigma_per_mm2, seidel_sigma_stddev_per_mm2, seidel_magnification, seidel_focal_mm;
  std::vector<ViewRms> views;
  // calibration.distortion_field.field_radius_px: radius about the principal point that the measurement uses
  // (optional; the distortion plot covers it).
  std::optional<double> field_radius_px;

  std::optional<SphereVerification> verification;
  PaperCornea paper;
  std::optional<DeviceStageRecord> device;

  // configuration.design and configuration.camera: what the record was computed with (absent in hand-made records).
  std::optional<model::Config> config;
  std::optional<model::TopographerCamera> topographer_camera;

  // The files themselves.
  calib::CalibrationFile calibration;
  std::string calibration_path;
  std::vector<CornerResidualRow> residuals;
  std::map<std::string, std::string> map_png;  // name under maps/ (e.g. "sphere_corrected_axial_power.png") -> bytes
};

// Reads and verifies the record in `directory`. Throws util::InputError "PATH: KEY: problem" for a missing or
// malformed file, a missing key, a value of the wrong type, another format or tool version, a file listed in
// `files` that is missing or whose SHA-256 differs.
UnitRecord ReadUnitRecord(const std::string& directory);

}  // namespace topocal::report
