#pragma once
// A null screen designed for the eyes it will see (`topocal design --optimize`, docs/screen-design.md).
//
// A bounded, deterministic grid search over the ideal image's density — N + 1 rings (Eq. 2a) and eta0 = eta spots
// added per ring (Eq. 2b) — with the pattern's extent (rho0_mm, rhoN_mm) and the topographer of the base
// configuration. Each candidate gets the largest spot radius (ideal image, µm) up to the goal's maximum that keeps
// its spots resolvable at the steepest cornea of the goal's range and on each of the goal's corneas, and is judged on
//   * resolvability: the smallest gap between neighbouring spot images on the detection plane, in pixels, at the
//     steepest and flattest corneas (spheres of those apex radii) and on the goal's corneas (whose ablation blends
//     and cones crowd the spots more than the steepest sphere does) against the detector's need (min_gap_px);
//   * printability: the page the printable screen (plot::NullScreenSvg) needs, the narrowest printed ellipse and the
//     narrowest printed gap between neighbouring ellipses;
//   * identification: the goal corneas' exact spots given to the pattern matcher (correct::IndexSpots); a wrong
//     identity, or none, refuses the candidate;
//   * map error: the tangential-map RMS of the goal's test corneas (model/freeform_test_set.h), each imaged through
//     the candidate — exact spots, or spots with the goal's centre noise — and reconstructed
//     (topo::MeasureSimulatedCornea) with each of the goal's knot spacings of the spline residual, the worst of them
//     the score. The spacing is part of the design: a denser screen carries the finer knots that its ablations'
//     blend zones need, and the chosen one goes into the configuration written.
// The choice: among the candidates that resolve and print, the fewest spots that meet max_tangential_rms_D when
// the goal states one; otherwise the lowest worst-case error, a design with fewer spots preferred when it is within
// kNegligibleErrorGain of it.
#include <algorithm>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "model/config.h"
#include "util/io.h"
#include "model/paper_topographer.h"

namespace topocal::pipeline {

// The goal (JSON, docs/screen-design.md; every key optional, defaults below).
struct ScreenDesignGoal {
  // The test corneas whose tangential-map RMS is the score (names of model::FreeformTestSet()).
  std::vector<std::string> corneas = {"lasik-myopic-4D", "lasik-myopic-6D", "lasik-hyperopic-4D",
                                      "lasik-hyperopic-6D", "kc-33um-0.85mm"};
  std::optional<double> max_tangential_rms_D;  // the worst cornea's RMS must not exceed it; none: the lowest
  std::string surface_model = "spline";        // reconstruction.surface_model the candidates are measured with
  double steepest_radius_mm = 6.5;             // apex radii of the corneas every spot must resolve on
  double flattest_radius_mm = 9.5;
  double pixel_pitch_um = model::kPaperPixelPitchUm;  // the sensor's (data/device.json)
  // Gap the detector needs between neighbouring spot images for their centres to be as good as a lone spot's
  // (3 px to segment them; docs/screen-design.md, "The resolvability criterion").
  double min_gap_px = 4.5;
  double max_spot_radius_um = 8.0;   // ideal-image spot radius: the paper's, and the largest tried
  // Below it a candidate is refused: a spot image of 2.2 px radius on the 1.12 um sensor, still flat-topped above a
  // 1 px PSF (its light is charged by spot_noise_px's scaling).
  double min_spot_radius_um = 2.5;
  double min_printed_feature_mm = 0.15;  // narrowest printed ellipse and printed gap between ellipses
  std::vector<double> max_page_mm = {297.0, 210.0};  // the page the sheet must fit, either way round (A4)
  std::vector<int> rings = {12, 16, 20, 22, 24, 26, 28};  // N + 1 of the grid
  std::vector<int> eta = {6, 8};                         // eta0 = eta of the grid: ring i holds eta * i spots
  // Knot spacings of the spline residual tried with every candidate (reconstruction.spline_spacing_mm); empty: the
  // base configuration's alone.
  std::vector<double> spline_spacing_mm = {0.33, 0.25, 0.2, 0.15};
  // Spot-centre noise (px, each coordinate, seeded) of spots of max_spot_radius_um; a smaller spot's is larger by
  // max_spot_radius_um / its radius (photon-limited: 1 / sqrt(flux), the flux as the spot's area). 0: exact spots.
  // The default is reconstruction.spot_uncertainty_um's 0.045 um (0.04 px), a conservative figure for a real capture:
  // topocal's own noisy renders carry 0.001-0.002 px (docs/screen-design.md).
  double spot_noise_px = 0.04;
  bool IsValid(std::string* why) const;
  // The candidates of the grid: rings x eta x knot spacings (at least one).
  size_t GridSize() const { return rings.size() * eta.size() * std::max<size_t>(1, spline_spacing_mm.size()); }
};

// Loads and validates a goal file: unknown keys, wrong types and values out of range throw util::ConfigError
// "FILE: KEY: problem" (a cornea name not in the test set included).
ScreenDesignGoal LoadScreenDesignGoal(const std::string& path);
ScreenDesignGoal ParseScreenDesignGoal(const std::string& json_text, const std::string& origin);

// A gain in the worst tangential RMS smaller than this fraction of it is not worth more spots: 0.04 px of spot
// noise moves the ablations' tangential RMS by 3-9 % (docs/reconstruction.md: 0.43-1.87 D exact, 0.44-2.03 D noisy).
inline constexpr double kNegligibleErrorGain = 0.05;
// The scan of corneas that still resolve: apex radii 5-12 mm (a keratoconus apex to a flat post-myopic cornea).
inline constexpr double kScanSteepestMm = 5.0, kScanFlattestMm = 12.0;

struct ScreenCandidate {
  model::IdealImageParams ideal;  // rings_N, eta0 = eta, spot_radius_um chosen; extent from the base config
  double spline_spacing_mm = 0;   // the knot spacing it is reconstructed with
  double spot_noise_px = 0;       // the spot-centre noise it is measured with (the goal's, scaled to its spots)
  bool base = false;              // the base configuration's own design, as given
  int spots = 0;
  // Resolvability (spheres at the goal's steepest / flattest apex radius).
  double min_spacing_steep_um = 0, min_spacing_flat_um = 0;  // nearest spot centres on the detection plane
  double min_gap_steep_px = 0, min_gap_flat_px = 0;          // nearest spot images' edges
  double min_gap_corneas_px = 0;  // the same on the goal's corneas (NaN: none imaged the pattern)
  // Identification: the smallest share of a goal cornea's spots the pattern matcher identifies (NaN: not tried —
  // the candidate was refused before — or a wrong identity, which refuses the candidate).
  double identified_share = 0;
  double steepest_resolved_mm = 0, flattest_resolved_mm = 0; // range that resolves (NaN: none), within the scan
  // Printability.
  double page_width_mm = 0, page_height_mm = 0;
  double min_printed_width_mm = 0, min_printed_gap_mm = 0;
  // Map error, per goal cornea (NaN: not measured — the candidate was refused before — or the analysis failed).
  std::vector<double> tangential_rms_D;
  double worst_tangential_rms_D = 0;  // NaN when not measured
  std::string refused;                // empty: resolves and prints; else the first constraint it breaks
  bool meets_goal = false;
};

struct ScreenDesignResult {
  std::vector<ScreenCandidate> candidates;  // grid order (rings, then eta), the base design first
  std::optional<size_t> chosen;             // index into candidates; none: the goal cannot be met
  std::string why;                          // why this one, or (no choice) "KEY: problem" naming the goal key
  model::Config config;                     // the base configuration with the chosen design (when chosen)
};

struct ScreenDesignOptions {
  int jobs = 0;  // threads (0: the cores available); the result does not depend on it
  std::function<void(size_t done, size_t total)> progress;  // called from worker threads
};

// Throws util::InputError if the goal is invalid (IsValid) or names a cornea not in the test set (the goal's
// reader refuses both as util::ConfigError first).
ScreenDesignResult OptimizeScreenDesign(const model::Config& base, const ScreenDesignGoal& goal,
                                        const ScreenDesignOptions& options = {});

// The trade-off as a Markdown table with the choice and its reason under it.
std::string ScreenDesignTable(const ScreenDesignResult& result, const ScreenDesignGoal& goal);

// Resolvability of one design at one apex radius (exposed for tests): the spots imaged by a sphere of that radius;
// neighbouring spots' centre spacing and the gap between their images, the image of a spot taken as its ideal
// circle scaled by the local magnification (the pair's image spacing over its ideal spacing). Also the largest
// spot radius that keeps gap_px >= min_gap_px. nullopt when a spot cannot be imaged.
struct SpotSpacing {
  double min_spacing_um = 0, min_gap_px = 0, max_spot_radius_um = 0;
};
std::optional<SpotSpacing> SpotSpacingAt(const model::IdealImageParams& ideal, const model::TopographerParams& topographer,
                                         double apex_radius_mm, double pixel_pitch_um, double min_gap_px);

}  // namespace topocal::pipeline
