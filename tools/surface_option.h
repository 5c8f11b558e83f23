#pragma once
// --biconic-fit and --surface-model, the options of every verb that reconstructs (reconstruct, detect, sweep).
#include <string>

#include <CLI/CLI.hpp>

#include "model/config.h"

namespace topocal::tools {

// Each overrides its configuration key when given.
struct ReconstructionOverrides {
  std::string biconic_fit, surface_model;
  void AddTo(CLI::App* cmd);
  void ApplyTo(model::Config* config) const;
};

}  // namespace topocal::tools
