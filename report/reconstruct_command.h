#pragma once
// `topocal reconstruct`: the cornea recovered from a spots CSV or a raw image (detected, indexed, undistorted with a
// calibration or measured through a device), its biconic fit, clinical numbers with their uncertainty, and the JSON
// and maps the user asked for. A measurement the data cannot support is refused (util::MeasurementRefused), its
// reasons printed and written to the JSON.
#include <functional>
#include <ostream>
#include <string>

#include "model/config.h"
#include "util/progress_display.h"

namespace topocal::report {

struct ReconstructRequest {
  std::string config_path;  // the topographer configuration (JSON)
  // The measurement: exactly one of a spots CSV (detection-plane mm) and a raw image.
  std::string spots_path, image_path;
  // For an image: the device it was taken through, and optionally a lens calibration put on its camera
  // (pipeline::LoadMeasuringDevice).
  std::string device_path, calibration_path;
  std::string estimator = "psf";         // spot centre estimator: psf, centroid or gaussian
  std::string eye;                       // OD or OS; empty: the configuration's
  std::string power_scale = "standard";  // the maps' power scale: standard, extended or fit
  double power_step_D = 0;               // with power_scale "fit"; 0: 0.5 D
  int uncertainty_samples = 0;           // Monte Carlo draws of the device's parameters; 0: linear
  unsigned seed = 1;                     // of those draws
  std::string json_path;                 // empty: no JSON
  std::string maps_dir;                  // empty: no maps
  bool truth = false;                    // compare with the configuration's cornea
  // Applied to the configuration once loaded (the command line's --biconic-fit and --surface-model); may be empty.
  std::function<void(model::Config*)> override_config;
  // Shows long uncertainty draws as they run; empty: nothing shown.
  util::ShowProgress progress;
};

// Prints the measurement, its fit and clinical numbers to `out` and publishes the JSON and maps together. Throws
// util::InputError for bad input and util::MeasurementRefused (after printing and writing the reasons) for a
// measurement the data cannot support.
void RunReconstruct(const ReconstructRequest& request, std::ostream& out);

}  // namespace topocal::report
