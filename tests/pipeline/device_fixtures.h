#pragma once
// Shared by the device tests: the bundled design and camera, and devices drawn within the assembly tolerances.
#include <random>
#include <string>

#include "model/config.h"
#include "model/device.h"
#include "pipeline/uncertainty_coverage.h"

namespace topocal::pipeline::testing {

inline model::Config PaperConfig() { return model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json"); }

inline model::Device NominalDevice() {
  return model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json").device;
}

// A device drawn within the assembly tolerances (pipeline::DrawAssembledDevice).
inline model::Device DrawDevice(std::mt19937& rng) { return DrawAssembledDevice(NominalDevice(), rng); }

}  // namespace topocal::pipeline::testing
