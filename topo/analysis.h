#pragma once
// From spot positions to clinical numbers: reconstruction, biconic fit, power maps and — when the true cornea is
// known — the height-difference errors of paper Eq. 26-27.
#include <optional>
#include <vector>

#include "model/config.h"
#include "model/null_screen.h"
#include "topo/biconic_fit.h"
#include "topo/clinical_indices.h"
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
  double covered_radius_mm = 0;          // radius the reconstructed points reach (farthest point)
  // Radius to which the data reach in EVERY direction: the smallest, over 36 sectors of 10 deg about the axis, of
  // the farthest point in the sector (an empty run of at most 3 sectors: the nearer reach of the sectors on either
  // side; a wider one: 0). Maps beyond it extrapolate in some direction; the clinical indices and the truth
  // comparisons use only the disc of this radius.
  double supported_radius_mm = 0;
  std::optional<SurfaceErrors> errors;   // when the truth is given
  ClinicalIndices clinical;              // within the covered radius (topo/clinical_indices.h)
  bool clinical_ok = false;
  std::string clinical_message;          // why the indices are missing, when they are
  bool maps_extrapolated = false;        // the maps reach beyond supported_radius_mm
  // Said in the JSON and on stdout: the surface model does not fit the data (adequacy ratio above
  // kAdequacyWarningRatio), the maps extrapolate beyond the data.
  std::vector<std::string> warnings;
};

// kAdequacyWarningRatio, kStructuredResidualWarningRatio and ModelFitsData: topo/reconstruction.h (the
// reconstruction's "auto" surface model decides with them).

PowerMapOptions PowerMapOptionsFrom(const model::ReconstructionSettings& settings);

// What an analysis computes beyond the reconstruction, the biconic parameters and the power maps, and where it
// starts. A Monte Carlo draw (pipeline/uncertainty.h) turns off what it does not read and starts from the nominal
// analysis of the same spots.
struct AnalysisOptions {
  bool stddev = true;     // the biconic's standard deviations
  bool adequacy = true;   // Reconstruction::expected_slope_noise, adequacy_ratio (and its warning)
  bool clinical = true;   // Analysis::clinical (sim-K, Kmax, best-fit sphere, I-S)
  // The analysis of nearly the same spots (a draw's nominal): its slope-fit factor starts this one's slope fits,
  // its recovered surface the refinement of the incidence points (ReconstructOptions::start) and its fit, in the same
  // mode, the biconic or sphere fit (BiconicFitOptions::start). The results agree with a cold analysis to the
  // refinement's convergence_um (not bit for bit). Starting the fit from the nominal with the cold fit's solver
  // settings was tried and took as many iterations (7-12: rounding-level steps at its 1e-14 tolerances); the warm
  // start's own settings take 3.
  const Analysis* start = nullptr;
  // Without `start`: the biconic or sphere fit alone starts from these parameters of a fit in the same mode
  // (BiconicFitOptions::start), the rest of the analysis as from cold. The harness starts every case's fit from
  // its cornea's truth fit (harness/harness.cc).
  const model::BiconicParams* fit_start = nullptr;
};

// Runs reconstruction, fit and maps. Throws std::runtime_error (one line) when the reconstruction or the fit fails.
Analysis AnalyzeSpots(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
                      const model::Config& config, const model::BiconicParams* truth,
                      const AnalysisOptions& options = {});

// Power maps of a known biconic (the "ideal" maps of paper Fig. 10c-d).
PowerMaps IdealPowerMaps(const model::BiconicParams& cornea, const model::ReconstructionSettings& settings);

// The supported radius of a point cloud (Analysis::supported_radius_mm).
double SupportedRadiusMm(const std::vector<ReconstructedPoint>& points);

// Eq. 26: Delta S = ideal - recovered at (x, y), mm: the true surface's sag there minus the recovered height
// recovered_z_mm; nullopt where the true surface is undefined. HeightErrors and the difference maps
// (pipeline/map_output.cc) both call it.
std::optional<double> HeightDifferenceMm(const model::Surface& truth, double x_mm, double y_mm,
                                         double recovered_z_mm) noexcept;

// Eq. 26-27 for a recovered point cloud against a known surface.
SurfaceErrors HeightErrors(const std::vector<ReconstructedPoint>& points, const model::Surface& truth);

}  // namespace topocal::topo
