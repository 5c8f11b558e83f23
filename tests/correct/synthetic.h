#pragma once
// Shared ground truth for the correct/ tests: the paper's configuration, the default camera, spot truth.
#include <string>

#include "correct/spot_truth.h"
#include "model/config.h"
#include "model/device.h"
#include "model/topographer_camera.h"

namespace topocal::correct::testing {

inline model::Config PaperConfig() { return model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json"); }

inline model::TopographerCamera DefaultCamera() {
  return model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json").device.camera;
}

inline model::SeidelParams Seidel(const model::Config& c, double sigma_per_mm2) {
  model::SeidelParams s;
  s.sigma_per_mm2 = sigma_per_mm2;
  s.magnification = c.distortion.magnification;
  return s;
}

inline SpotTruth Truth(const model::Config& c, const model::BiconicParams& cornea, double sigma_per_mm2,
                       const model::TopographerCamera& camera) {
  return SpotsOnSensor(model::Biconic{cornea}, c.ideal_image, c.topographer, Seidel(c, sigma_per_mm2), camera);
}

}  // namespace topocal::correct::testing
