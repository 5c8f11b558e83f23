#pragma once
// JSON fragments of a reconstruction's analysis, shared by the verbs that report one (sweep, reconstruct): the
// fitted surface, the reconstruction, errors, clinical indices, model adequacy, the Taylor polynomial; and the
// document `topocal sweep --json` writes, built from them.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "correct/detect_and_index.h"
#include "pipeline/capture_quality.h"
#include "pipeline/closed_loop.h"
#include "pipeline/measurement_uncertainty.h"
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

// The capture-quality block of `detect --json` and `reconstruct --json` (pipeline/capture_quality.h).
nlohmann::json CaptureJson(const pipeline::CaptureQuality& q);
// `topocal detect --json` (without "image", which the caller adds): counts, missing identities, the noise model and
// where its figures came from, the orientation check, the capture quality.
nlohmann::json DetectionJson(const correct::DetectAndIndexResult& r, correct::CentroidMethod estimator,
                             const pipeline::CaptureQuality& capture);
// The measurement part of `topocal reconstruct --json`: reconstruction, polynomial, surface fit, power, clinical,
// adequacy, and with `truth` the errors against it.
nlohmann::json MeasurementJson(const topo::Analysis& a, bool truth);
// The "uncertainty" block of `reconstruct --json` through a device: coverage factor, sources, and per quantity (by
// its place in the JSON, e.g. "clinical.kmax.power_D") the value, U (k = 2) and each source's standard uncertainty.
nlohmann::json MeasurementUncertaintyJson(const pipeline::MeasurementUncertainty& u);
// A measurement's JSON (MeasurementJson) with every value the data do not determine (QuantityUncertainty::
// determined false: a peak's location with a twin within U) set to null, at the path its name gives.
void WithdrawUndetermined(const pipeline::MeasurementUncertainty& u, nlohmann::json* measurement);

// `topocal sweep --json`: every sigma's row (image ellipse, fit, reconstruction, errors, clinical, adequacy) and,
// with --correct, `corrected[i]` beside row i (corrected may be shorter than the rows, or empty); ideal power and
// timings. Pretty-printed, two-space indent, with a final newline.
std::string SweepJson(const topo::SweepResult& r, const std::vector<pipeline::ClosedLoopResult>& corrected);

}  // namespace topocal::report
