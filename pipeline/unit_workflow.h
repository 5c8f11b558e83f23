#pragma once
// The per-unit calibration workflow of `topocal unit calibrate` and `unit calibrate-batch`: calibrate a unit's
// camera from target images, verify it on a reference sphere, simulate the paper's cornea through it and, with
// reference balls, calibrate the whole device. The result is written as a unit record (docs/unit-record.md) by
// report::WriteUnitRecord (report/unit_record_writer.h), beside the record's reader: the computation is owned here,
// the file format by report/ (report links pipeline, never the other way).
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "model/config.h"
#include "model/device.h"
#include "model/topographer_camera.h"
#include "pipeline/device_calibration.h"
#include "pipeline/device_verification.h"
#include "pipeline/unit_verification.h"

namespace topocal::pipeline {

struct UnitRequest {
  std::string serial;
  std::string target;                 // target description (Kalibr YAML)
  std::vector<std::string> images;    // target images, in order (one = single-view calibration)
  std::string config;                 // topographer design (JSON)
  std::string reference_sphere;       // raw spot image of the reference sphere; empty = no verification
  double sphere_radius_mm = 0;
  // Further images of the same reference sphere, the ball taken out and seated again between captures: each is
  // measured as the reference sphere is (without Monte Carlo draws), and the sample standard deviations of the
  // corrected radius and central power over all of them are the repeatability the QA report's budget uses.
  std::vector<std::string> sphere_repeats;
  // The device stage: reference-ball images and their certified radii; empty = lens-only calibration.
  // The reference sphere, when given, is then a held-out ball measured through the calibrated device too.
  std::vector<std::string> balls;
  std::vector<double> ball_radii_mm;
  std::string device;                 // the unit's nominal device (JSON): its camera, and where the device stage starts
  std::string model = "seidel";       // seidel | brown5
  bool fit_centre = false;
  std::vector<std::string> fixed;     // parameters held at their initial value (calib::CameraParameterNames)
  double fixed_aspect_ratio = 0;      // fx / fy held during a multi-view fit (calib::CalibrationOptions); 0 = free
  // A calibration with a parameter the views do not determine (calib/parameter_range.h) is refused unless this is
  // set; the record then lists the parameter under calibration.undetermined.
  bool allow_undetermined = false;
  UncertaintySetting uncertainty;     // how the checks carry the covariance (--uncertainty; linear unless told)
  unsigned seed = 1;                  // of the Monte Carlo draws
  int jobs = 0;                       // threads for the checks' analyses (0 = every core; same record either way)
  std::string out;                    // the record directory, named after the serial (units/SN/)
  // A record already at `out` is refused (nothing computed); with keep_history (--force) it is moved to
  // <parent>/.history/<serial>/<its created_utc>/ when the new one is in place (docs/unit-record.md).
  bool keep_history = false;
  // The CSV grid beside each map PNG in maps/ (~3 MB each, 16 maps: ~47 MB); off, the record holds the PNGs only and
  // its numbers in unit.json (a few MB in all).
  bool map_csv = false;
  // How the record names an input file instead of its path: the data bundled with topocal as "bundled:NAME", so that
  // a record does not carry the build or install tree's location (the digest still pins the content).
  std::map<std::string, std::string> input_names;
};

// Where --force keeps the records a unit's new record replaces: <parent>/.history/<serial>/ (hidden, so that a glob
// of records, `units/*/`, does not take it for one).
std::filesystem::path RecordHistoryDir(const std::filesystem::path& record);

// One input file of the unit and its SHA-256 (the record's provenance).
struct UnitInputDigest {
  std::string role;  // config, device, target, image, reference_sphere, reference_sphere_repeat, ball
  std::string path, sha256;
};

// The camera calibration of the unit and the images it used.
struct UnitCameraCalibration {
  calib::CalibrationResult result;
  std::vector<std::string> view_paths;  // parallel to the views the calibration was given
  std::vector<calib::ViewObservations> views_used;  // the corners of the views it used: the device stage fits them too
  bool single_view = false;
};

// The size of the calibrated distortion over the spot pattern's field on the detection plane.
struct DistortionField {
  double field_radius_mm = 0;  // the outermost spot of the configured cornea
  double max_um = 0, max_px = 0;
};

// The reference sphere measured again from its repeated captures (UnitRequest::sphere_repeats): the corrected
// radius and central axial power of every image, the reference sphere's own first.
struct SphereRepeats {
  std::vector<double> radius_mm, central_axial_power_D;
};

// The device stage: the device fitted to the balls, and what it is worth beside the lens-only calibration.
struct UnitDeviceStage {
  DeviceCalibration calibration;
  model::Device lens_only;
  std::optional<HeldOutBall> held_out;
  ThreeWay paper;
};

// Everything the unit record holds, computed; nothing written yet.
struct UnitResult {
  UnitRequest request;
  std::string created_utc;  // SOURCE_DATE_EPOCH when set (reproducible reruns), else now; ISO 8601 UTC
  model::Config config;               // as read (the record keeps its canonical form)
  model::TopographerCamera camera;    // as read
  std::vector<UnitInputDigest> inputs;
  UnitCameraCalibration calibration;
  DistortionField field;
  CheckOptions check;
  std::optional<SphereVerification> sphere;  // with a reference sphere
  std::optional<SphereRepeats> sphere_repeats;  // with repeated images of it
  SimulatedCornea paper;
  std::optional<UnitDeviceStage> device;     // with reference balls
};

// Runs the whole workflow. Throws util::InputError / util::ConfigError for bad input (exit 2) and
// std::runtime_error for a computation that failed (exit 1); every input is read and checked before any work.
// `log` receives warnings (skipped images), one line each.
UnitResult CalibrateUnit(const UnitRequest& request, const std::function<void(const std::string&)>& log);

// The lines for the terminal: calibration, distortion, reference sphere, paper cornea, device stage, record path.
std::vector<std::string> UnitSummary(const UnitResult& unit);

// A unit directory of a batch: DIR/<name>/unit-inputs.json (docs/unit-record.md, "Batch"), paths relative to it.
// Fields the file leaves out come from `defaults`. Throws util::InputError naming the file and key.
UnitRequest ReadUnitInputs(const std::string& path, const UnitRequest& defaults);

// The serial as a directory and report-id component: 1-64 characters of [A-Za-z0-9._-], not starting with '.'.
bool IsValidSerial(const std::string& serial);

}  // namespace topocal::pipeline
