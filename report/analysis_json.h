#pragma once
// JSON fragments of a reconstruction's analysis, shared by the verbs that report one (sweep, reconstruct): the
// fitted surface, the reconstruction, errors, clinical indices, model adequacy, the Taylor polynomial.
#include <nlohmann/json.hpp>

#include "topo/analysis.h"

namespace topocal::report {

nlohmann::json SurfaceFitJson(const topo::BiconicFit& fit);
nlohmann::json ReconstructionJson(const topo::Reconstruction& r);
// "pv_tangential_D", "pv_axial_D", map and covered radius; "pv_um", "rms_um" when the truth was known.
nlohmann::json ErrorsJson(const topo::Analysis& a);
nlohmann::json PolynomialJson(const topo::TaylorPolynomial& p);
// Clinical indices (sim-K, Kmax, BFS elevation, I-S), or {"error": why} when they could not be computed.
nlohmann::json ClinicalJson(const topo::Analysis& a);
// Model adequacy (slope residual against the expected spot noise), map coverage and the warnings.
nlohmann::json AdequacyJson(const topo::Analysis& a);

}  // namespace topocal::report
