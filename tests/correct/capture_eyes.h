#pragma once
// The capture test set of the spot identities (tests/correct/spot_index_capture_test.cc) and of the surface's
// labelling (tests/pipeline/surface_labelling_test.cc): decentred and tilted eyes far from any biconic, and
// assembled devices.
#include <cmath>
#include <string>
#include <vector>

#include "model/device.h"
#include "model/freeform_test_set.h"
#include "model/surface.h"
#include "tests/correct/synthetic.h"

namespace topocal::correct::testing {

struct Eye {
  std::string name;
  model::Surface surface;
  bool extreme_ablation = false;  // the +6 D hyperopic and -8 D myopic ablations: share bounds of their own
};

inline std::vector<Eye> Eyes() {
  const auto cfg = PaperConfig();
  std::vector<Eye> eyes;
  model::BiconicParams paper = cfg.cornea;
  paper.x0_mm = 0.35;  // decentred and tilted: an eye is never on the axis
  paper.y0_mm = -0.3;
  paper.tilt_x_deg = 2.0;
  paper.tilt_y_deg = -1.5;
  model::Biconic b{paper};
  model::FocusOnAxis(&b);
  eyes.push_back({"paper cornea decentred 0.46 mm, tilted 2.5 deg", b});
  for (const auto& c : model::FreeformTestSubset({"kc-14um-0.87mm-nipple", "kc-33um-0.85mm", "kc-40um-1.5mm",
                                                  "lasik-myopic-6D", "lasik-hyperopic-6D", "irregular-coma-trefoil"})) {
    eyes.push_back({c.name, c.surface, c.name == "lasik-hyperopic-6D"});
  }
  // Beyond the set: a severe central cone and a deep myopic ablation, decentred.
  model::Freeform severe = std::get<model::Freeform>(eyes[2].surface);
  severe.cones = {{60.0, 1.0, 0.4, -0.8}};
  model::FocusOnAxis(&severe);
  eyes.push_back({"kc-60um-1.0mm at (0.4, -0.8)", severe});
  model::Freeform deep = std::get<model::Freeform>(eyes[4].surface);
  deep.ablations = {{-8.0, 6.0, 1.0, 0.3, -0.2}};
  model::FocusOnAxis(&deep);
  eyes.push_back({"lasik-myopic-8D decentred", deep, true});
  return eyes;
}

// The screen `design --optimize` chooses for the default goal (docs/screen-design.md): 26 rings x 6, spots of
// 2.70 um; the rest of `ideal` kept.
inline model::IdealImageParams DesignedScreen(model::IdealImageParams ideal) {
  ideal.rings_N = 25;
  ideal.eta0 = ideal.eta = 6;
  ideal.spot_radius_um = 2.70;
  return ideal;
}

inline model::Device AssembledDevice(int variant) {
  model::Device device = model::NominalDevice(DefaultCamera());
  if (variant == 0) return device;
  const double az = variant * 2.1;
  device.screen = {1.2 * std::cos(az), 1.2 * std::sin(az), 0.8, 0.15, -0.2, 0.4, 1.0};
  device.camera.principal_point_px += Eigen::Vector2d(20 * std::cos(az), -15 * std::sin(az));
  model::SeidelParams seidel;
  seidel.sigma_per_mm2 = variant % 2 ? 6.3e-5 : -6.3e-5;
  device.distortion = seidel;
  return device;
}

}  // namespace topocal::correct::testing
