#pragma once
// JSON fragments of a reconstruction's analysis, shared by the verbs that report one (sweep, reconstruct): the
// fitted surface, the reconstruction, errors, clinical indices, model adequacy, the Taylor polynomial; and the
// document `topocal sweep --json` writes, built from them.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pipeline/closed_loop.h"
#include "topo/analysis.h"
#include "topo/sweep.h"

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

// `topocal sweep --json`: every sigma's row (image ellipse, fit, reconstruction, errors, clinical, adequacy) and,
// with --correct, `corrected[i]` beside row i (corrected may be shorter than the rows, or empty); ideal power and
// timings. Pretty-printed, two-space indent, with a final newline.
std::string SweepJson(const topo::SweepResult& r, const std::vector<pipeline::ClosedLoopResult>& corrected);

}  // namespace topocal::report
