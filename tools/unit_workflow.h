#pragma once
// The per-unit calibration workflow of `topocal unit calibrate` and `unit calibrate-batch`: calibrate a unit's
// camera from target images, verify it on a reference sphere, simulate the paper's cornea through it, and write
// the unit record (docs/unit-record.md) atomically.
#include <functional>
#include <string>
#include <vector>

namespace topocal::tools {

// Monte Carlo draws of a unit's verification: the range of --uncertainty and of unit-inputs.json's
// uncertainty_samples (200 draws take ~1 s; 1e5 bounds the work at a few minutes per unit).
inline constexpr int kMaxUncertaintySamples = 100000;

struct UnitRequest {
  std::string serial;
  std::string target;                 // target description (Kalibr YAML)
  std::vector<std::string> images;    // target images, in order (one = single-view calibration)
  std::string config;                 // topographer design (JSON)
  std::string camera;                 // topographer camera (JSON)
  std::string reference_sphere;       // raw spot image of the reference sphere; empty = no verification
  double sphere_radius_mm = 0;
  // The device stage (issue 19): reference-ball images and their certified radii; empty = lens-only calibration.
  // The reference sphere, when given, is then a held-out ball measured through the calibrated device too.
  std::vector<std::string> balls;
  std::vector<double> ball_radii_mm;
  std::string device;                 // nominal device (JSON); empty = the camera with no distortion, screen nominal
  std::string model = "seidel";       // seidel | brown5
  bool fit_centre = false;
  std::vector<std::string> fixed;     // parameters held at their initial value (calib::kParameterNames)
  int uncertainty_samples = 200;      // Monte Carlo draws; 0 = none, else 2 to kMaxUncertaintySamples
  unsigned seed = 1;
  int jobs = 0;                       // threads for the Monte Carlo draws (0 = every core; same record either way)
  std::string out;                    // the record directory
};

struct UnitOutcome {
  std::string serial;
  std::string out;
  std::vector<std::string> summary;  // lines for the terminal
};

// Runs the whole workflow and writes the record. Throws model::InputError / model::ConfigError for bad input
// (exit 2) and std::runtime_error for a computation that failed (exit 1); in both cases nothing is written and an
// existing record at `out` is left as it was. `log` receives warnings (skipped images), one line each.
UnitOutcome CalibrateUnit(const UnitRequest& request, const std::function<void(const std::string&)>& log);

// A unit directory of a batch: DIR/<name>/unit-inputs.json (docs/unit-record.md, "Batch"), paths relative to it.
// Fields the file leaves out come from `defaults`. Throws model::InputError naming the file and key.
UnitRequest ReadUnitInputs(const std::string& path, const UnitRequest& defaults);

// The serial as a directory and report-id component: 1-64 characters of [A-Za-z0-9._-], not starting with '.'.
bool IsValidSerial(const std::string& serial);

}  // namespace topocal::tools
