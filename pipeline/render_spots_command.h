#pragma once
// `topocal render-spots`: the raw sensor image of a measurement (the spot pattern of the configured cornea or of a
// reference ball, distorted, seen by the topographer's camera or an as-built device), with the artefacts of a real
// capture on request, and its truth. Conventions: docs/camera-conventions.md.
#include <cmath>
#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "model/config.h"
#include "model/surface.h"
#include "util/progress_display.h"

namespace topocal::pipeline {

struct RenderSpotsRequest {
  std::string config_path;
  std::string device_path;               // the device imaged through
  std::string out_path;                  // the image (.png)
  std::string truth_path;                // truth CSV; empty: none
  std::string spot = "ellipse";          // spot model: ellipse or psf
  std::optional<double> sigma_per_mm2;   // the configuration's Seidel distortion at sigma instead of the device's
  double psf_px = 1.0, drop_fraction = 0, sphere_radius_mm = 0, upper_lid_fraction = 0, lower_lid_fraction = 0;
  std::vector<double> ball_at_mm;  // vertex of the reference ball (x, y, z); empty: the origin
  // NaN: the bit depth's default (a well-exposed frame with realistic read and shot noise).
  double background_dn = NAN, peak_dn = NAN, read_noise_dn = NAN, gain_e_per_dn = NAN;
  double lid_skin_dn = 0, iris_dn = 0, defocus_rim_px = 0, motion_blur_px = 0, motion_blur_deg = 0;
  int bits = 16, glints = 0, lashes = 0, tear_film_patches = 0;
  uint32_t seed = 1;
  util::LogLine log;  // warnings beside the result: spots not imaged or off the sensor
};

// Writes the image and the truth together and says so on `out`; spots not imaged or off the sensor on `log`.
// util::InputError for bad input; std::runtime_error when the surface images no spot.
void RunRenderSpots(const RenderSpotsRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
