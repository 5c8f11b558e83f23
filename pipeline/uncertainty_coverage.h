#pragma once
// Is the reported U honest? (docs/uncertainty.md). Seeded cases, each an assembled device drawn
// within the assembly tolerances, calibrated from three reference balls placed at random (noisy spot centres), and
// an eye from topocal's test set (keratoconus, ablations, irregular astigmatism, biconics; apex off the axis, eye
// tilted) or the paper cornea, imaged through the true device with the same spot noise and measured through the
// calibrated one with its U (PropagateMeasurementUncertainty). Each quantity's pull (value - truth) / (U / 2) is
// collected, the truth being the same analysis of the exact spots through the true device (what a perfect
// calibration and a noise-free image give: reconstruction's own method error is not the calibration's). The device
// parameters' pulls (fit - truth) / sd are collected too.
//
// An honest U (k = 2) covers ~95 % of the cases and its pulls have RMS ~1. Run by bench/uncertainty_coverage
// (the table of docs/uncertainty.md) and, small, by the tests.
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "model/config.h"
#include "model/device.h"
#include "util/io.h"

namespace topocal::pipeline {

struct CoverageOptions {
  int cases = 100;
  std::uint32_t seed = 1;          // case i draws everything from std::seed_seq{seed, i}
  double spot_noise_px = 0.04;     // per axis, on every ball and eye spot centre
  int spot_draws = 16;             // UncertaintyOptions::spot_draws
  // Empty: the paper cornea and the whole test set in turn; "biconic", "keratoconus", "ablation", "irregular": the
  // paper cornea and that kind only.
  std::string eye_kind;
  int jobs = 0;                    // cases in parallel (<= 0: every core); the result does not depend on it
};

struct CoverageRow {
  std::string quantity;
  int n = 0;                       // cases that reported it
  double covered = 0;              // share with |value - truth| <= U (k = 2)
  double pull_rms = 0;             // rms of (value - truth) / (U / 2); sd pulls for device parameters
  double max_abs_pull = 0;
};

// The measurement's rows for the eyes measured with one surface model (the polynomial represents the biconic and
// mildly irregular eyes; "auto" brings in the spline for cones and ablations).
struct CoverageGroup {
  std::string surface_model;
  int cases = 0;
  std::vector<CoverageRow> rows;   // per reported quantity
  CoverageRow overall;             // every quantity together but the peaks' locations (bimodal: see their rows) and
                                   // the U's marked lower bounds
  CoverageRow lower_bounds;        // the U's marked lower bounds (QuantityUncertainty::lower_bound) together
};

struct CoverageResult {
  int cases = 0;
  int failed = 0;                  // cases whose device fit or measurement failed (counted, not hidden)
  std::vector<std::string> failures;  // why, one line each
  std::vector<CoverageGroup> measurement;  // by surface model
  std::vector<CoverageRow> device;         // per device parameter (fit - truth) / sd; "covered": within 2 sd
  const CoverageGroup* Group(const std::string& surface_model) const;
};

// A device drawn within the assembly tolerances of the device issue (uniform: cone tilt and roll +-1 deg,
// decentration +-0.2 mm, +-0.5 mm along the axis, principal point +-0.03 mm, a +-1 %) with the paper's lens
// (Seidel sigma = +-6.3e-5 per mm^2, Table VI), about `nominal`.
model::Device DrawAssembledDevice(const model::Device& nominal, std::mt19937& rng);

// `nominal`: the device the unit is designed as (its camera; the drawn devices depart from it). Throws
// util::InputError for cases < 1 or a non-positive noise.
CoverageResult RunUncertaintyCoverage(const model::Config& config, const model::Device& nominal,
                                      const CoverageOptions& options = {});

}  // namespace topocal::pipeline
