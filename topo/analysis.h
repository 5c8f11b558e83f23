#pragma once
// From spot positions to clinical numbers: reconstruction, biconic fit, power maps and — when the true cornea is
// known — the height-difference errors of paper Eq. 26-27.
#include <optional>
#include <vector>

#include "model/config.h"
#include "model/null_screen.h"
#include "topo/biconic_fit.h"
#include "topo/power_map.h"
#include "topo/reconstruction.h"

namespace topocal::topo {

struct SurfaceErrors {
  double pv_um = 0;   // Eq. 27a of Delta S = ideal biconic - recovered surface, over the recovered points
  double rms_um = 0;  // Eq. 27b
};

struct Analysis {
  Reconstruction reconstruction;
  BiconicFit surface_fit;
  PowerMaps power;                       // of Psi with piston and tilts removed (Sec. 4.2)
  double covered_radius_mm = 0;          // radius the reconstructed points reach; maps beyond it extrapolate
  std::optional<SurfaceErrors> errors;   // when the truth is given
};

PowerMapOptions PowerMapOptionsFrom(const model::ReconstructionSettings& settings);

// Runs reconstruction, fit and maps. Throws std::runtime_error (one line) when the reconstruction or the fit fails.
Analysis AnalyzeSpots(const std::vector<MeasuredSpot>& spots, const std::vector<model::TargetPoint>& targets,
                      const model::Config& config, const model::BiconicParams* truth);

// Power maps of a known biconic (the "ideal" maps of paper Fig. 10c-d).
PowerMaps IdealPowerMaps(const model::BiconicParams& cornea, const model::ReconstructionSettings& settings);

// Eq. 26-27 for a recovered point cloud against a known surface.
SurfaceErrors HeightErrors(const std::vector<ReconstructedPoint>& points, const model::Surface& truth);

}  // namespace topocal::topo
