#include "tools/surface_option.h"

namespace topocal::tools {

void ReconstructionOverrides::AddTo(CLI::App* cmd) {
  cmd->add_option("--biconic-fit", biconic_fit,
                  "Biconic fit: free-apex (apex position and tilt of the eye free; default) or paper (the paper's "
                  "6 parameters, apex on the axis) or sphere (centre and radius: a test ball); overrides "
                  "reconstruction.biconic_fit")
      ->check(CLI::IsMember({"free-apex", "paper", "sphere"}));
  cmd->add_option("--surface-model", surface_model,
                  "Surface: polynomial (the paper's Psi), spline (Psi plus a REML-smoothed spline residual: "
                  "keratoconus, ablations) or auto (the spline only where the polynomial does not fit the data); "
                  "overrides reconstruction.surface_model. Neither given: auto in reconstruct, polynomial elsewhere")
      ->check(CLI::IsMember({"polynomial", "spline", "auto"}));
}

void ReconstructionOverrides::ApplyTo(model::Config* config) const {
  if (!biconic_fit.empty()) config->reconstruction.biconic_fit = biconic_fit;
  if (!surface_model.empty()) {
    config->reconstruction.surface_model = surface_model;
    config->reconstruction.surface_model_given = true;
  }
}

}  // namespace topocal::tools
