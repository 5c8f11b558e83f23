#pragma once
// How far a reconstruction is from a known cornea, in the terms of topocal's freeform accuracy targets, over the
// area the data cover: axial and tangential map errors (RMS and max), height RMS, Kmax and its location, cone height
// (elevation peak above the best-fit sphere), sim-K. Both surfaces are compared as shapes: each with its own
// tangent plane at the origin removed (what Sec. 4.2 does to Psi before its maps).
#include "model/config.h"
#include "model/surface.h"
#include "topo/analysis.h"

namespace topocal::topo {

struct TruthComparison {
  double radius_mm = 0;  // compared within this radius (the supported radius, at most the map radius)
  double axial_rms_D = 0, axial_max_D = 0;
  double tangential_rms_D = 0, tangential_max_D = 0;
  double height_rms_um = 0;  // of the recovered points (HeightErrors, piston removed)
  double kmax_error_D = 0;   // recovered - true
  double kmax_location_error_mm = 0;
  // Cone height: the elevation peak above the best-fit biconic (free apex; the "best-fit toric ellipsoid" of
  // clinical elevation maps), within the supported disc — the same procedure on the truth (fitted at the
  // recovered points' (x, y)) and on the reconstruction (its own biconic fit).
  double cone_height_true_um = 0, cone_height_recovered_um = 0;
  Eigen::Vector2d cone_true_at_mm = Eigen::Vector2d::Zero(), cone_recovered_at_mm = Eigen::Vector2d::Zero();
  double steep_k_error_D = 0, flat_k_error_D = 0;
  ClinicalIndices truth;  // the true cornea's indices over the same radius
};

// Throws std::runtime_error when the true surface's maps or indices cannot be computed over the covered radius.
TruthComparison CompareWithTruth(const Analysis& analysis, const model::Surface& truth,
                                 const model::ReconstructionSettings& settings);

// A simulated measurement of a known cornea: its exact spots (model::SynthesizeImage through the configured
// design), optionally with Gaussian noise of spot_noise_mm on each image coordinate (seeded), analysed with the
// configuration's settings and compared with the truth. Throws std::runtime_error when the analysis fails.
struct SimulatedMeasurement {
  Analysis analysis;
  TruthComparison comparison;
  int spots = 0;
};
SimulatedMeasurement MeasureSimulatedCornea(const model::Surface& truth, const model::Config& config,
                                            double spot_noise_mm = 0.0, unsigned seed = 1);

}  // namespace topocal::topo
