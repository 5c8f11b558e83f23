#pragma once
// The sigma sweep (paper Sec. 5): for each distortion level of the configuration, synthesise the spot image of the
// configured cornea, distort it, and measure what the distortion does — the image contour (Table V), and, in later
// stages, the reconstructed surface, its biconic fit and power maps (Tables VI, VII).
#include <optional>
#include <string>
#include <vector>

#include "model/config.h"
#include "model/ellipse_fit.h"
#include "model/null_screen.h"
#include "topo/analysis.h"

namespace topocal::model {
struct Device;
}  // namespace topocal::model

namespace topocal::topo {

struct SweepRow {
  double sigma_per_mm2 = 0;
  model::Ellipse image_ellipse;
  double area_change_pct = 0;  // E_A: area change against the sigma = 0 contour
  int spots_imaged = 0;
  Analysis analysis;            // reconstruction, biconic fit (Table VI), power maps and errors (Table VII)
};

struct SweepTiming {
  double design_ms = 0;
  double synthesis_ms = 0;
  double analysis_ms = 0;  // reconstruction + biconic fit + power maps, summed over the sigmas (thread time)
  double total_ms = 0;
};

struct SweepResult {
  int spots = 0;  // designed spots
  std::vector<SweepRow> rows;
  std::vector<model::SpotFailure> design_failures;
  std::vector<model::SpotFailure> synthesis_failures;  // spots the cornea does not image (same for every sigma)
  PowerMaps ideal_power;  // maps of the configured (true) cornea
  SweepTiming timing;
  // Swept through a device: the cornea measured through it with its geometry and the sigma known (what the calibrated
  // unit reports; one answer for every sigma, which is undone exactly). The rows are then what the unit reports
  // uncalibrated: its assembly and the sigma both left in, the design assumed.
  std::optional<Analysis> through_device;
};

// Throws std::runtime_error with a one-line message when the configuration cannot be swept (no spot images, etc.).
// The sigmas run on `jobs` threads (0: every core, util::ParallelFor); the result does not depend on `jobs`.
// `device`: image the cornea through this as-built device (its screen pose and a; its own distortion replaced by
// each sigma of the configuration) instead of the design.
SweepResult RunSweep(const model::Config& config, int jobs = 0, const model::Device* device = nullptr);

// The distorted spot image of the configured cornea for one sigma (as `topocal simulate` writes it).
model::SyntheticImage SimulateSpots(const model::Config& config, double sigma_per_mm2);

}  // namespace topocal::topo
