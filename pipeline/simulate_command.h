#pragma once
// `topocal simulate`: the (distorted) spot positions of the configured cornea on the detection plane, at a Seidel
// sigma of the configuration's design or through an as-built device (which may image a reference ball instead).
#include <cmath>
#include <ostream>
#include <string>
#include <vector>

#include "model/config.h"
#include "model/surface.h"
#include "util/progress_display.h"

namespace topocal::pipeline {

struct SimulateRequest {
  std::string config_path;
  double sigma_per_mm2 = NAN;  // exactly one of a sigma and a device
  std::string device_path;
  double sphere_radius_mm = 0;     // with a device: image a reference ball of this radius instead (0: the cornea)
  std::vector<double> ball_at_mm;  // its vertex (x, y, z); empty: the origin
  std::string out_path;            // the spots CSV
  util::LogLine log;  // warnings beside the result: the spots not imaged
};

// Writes the spots CSV and says so on `out`; the spots not imaged on `log`. util::InputError for bad input;
// std::runtime_error when the surface images no spot.
void RunSimulate(const SimulateRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
