#pragma once
// Shared by the device tests: the bundled design and camera, and devices drawn within the assembly tolerances.
#include <random>
#include <string>

#include "model/config.h"
#include "model/device.h"

namespace topocal::pipeline::testing {

inline model::Config PaperConfig() { return model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json"); }

inline model::Device NominalDevice() {
  return model::NominalDevice(model::LoadTopographerCamera(std::string(TOPOCAL_SOURCE_DIR) + "/data/camera.json"));
}

// A device drawn within the assembly tolerances of issue 19 (cone tilt and roll 1 deg, decentration 0.2 mm, 0.5 mm
// along the axis, principal point 0.03 mm, a 1 %), with the paper's lens: sigma = +-6.3e-5 (Table VI).
inline model::Device DrawDevice(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  model::Device d = NominalDevice();
  d.screen.rx_deg = u(rng);
  d.screen.ry_deg = u(rng);
  d.screen.rz_deg = u(rng);
  d.screen.tx_mm = 0.2 * u(rng);
  d.screen.ty_mm = 0.2 * u(rng);
  d.screen.tz_mm = 0.5 * u(rng);
  d.camera.principal_point_px += Eigen::Vector2d(0.03 * u(rng), 0.03 * u(rng)) / d.camera.PitchMm();
  d.camera.a_mm *= 1.0 + 0.01 * u(rng);
  model::SeidelParams s;
  s.sigma_per_mm2 = u(rng) < 0 ? -6.3e-5 : 6.3e-5;
  d.distortion = s;
  return d;
}

}  // namespace topocal::pipeline::testing
