#pragma once
// The surface a simulation verb images: the configuration's cornea, or a reference ball (--sphere-radius-mm R) with
// its vertex at --ball-at X Y Z (default the origin). One place for both options' checks (simulate, render-spots).
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "model/config.h"
#include "model/surface.h"

namespace topocal::tools {

// Throws util::InputError naming the option for a non-physical radius, --ball-at without a radius, or a vertex
// more than 5 mm from the cornea position.
model::Surface SurfaceToImage(const model::Config& config, double sphere_radius_mm, const std::vector<double>& ball_at_mm);

// --sigma of a simulation verb (simulate, render-spots): throws util::InputError when the Seidel sigma folds the
// configuration's image (|sigma| at or beyond model::MaxFoldFreeSigmaPerMm2; 1e308 wrote rows of -inf).
void RequireFoldFreeSigma(double sigma_per_mm2, const model::Config& config, const std::string& config_path);

// --biconic-fit and --surface-model (reconstruct, sweep): each overrides its configuration key when given.
struct ReconstructionOverrides {
  std::string biconic_fit, surface_model;
  void AddTo(CLI::App* cmd);
  void ApplyTo(model::Config* config) const;
};

}  // namespace topocal::tools
