#pragma once
// `topocal detect`: the spots of a raw image detected, indexed and flagged with the chosen estimator, every identity
// checked against the surface the others give; written as a spots CSV and a JSON summary, or refused (no spots file,
// util::MeasurementRefused) when the data cannot support the identities.
#include <functional>
#include <ostream>
#include <string>

#include "model/config.h"

namespace topocal::report {

struct DetectRequest {
  std::string image_path;  // the raw sensor image
  // The device the image was taken through, and optionally a lens calibration put on its camera
  // (pipeline::LoadMeasuringDevice).
  std::string device_path, calibration_path;
  std::string config_path;        // the topographer configuration (JSON)
  std::string out_path;           // the spots CSV
  std::string json_path;          // the summary JSON; empty: none
  std::string estimator = "psf";  // spot centre estimator: psf, centroid or gaussian
  // Applied to the configuration once loaded (the command line's --biconic-fit and --surface-model: the surface the
  // identities are checked against, as reconstruct's); may be empty.
  std::function<void(model::Config*)> override_config;
};

// Writes the CSV and the JSON together and prints the counts to `out`. Throws util::InputError for bad input and
// util::MeasurementRefused (after printing the reasons and writing the JSON) for identities the data cannot support.
void RunDetect(const DetectRequest& request, std::ostream& out);

}  // namespace topocal::report
