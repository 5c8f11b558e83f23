// Is the reported U honest? The coverage table (docs/uncertainty.md): seeded assembled
// devices calibrated from three noisy ball images, eyes of topocal's test set measured through them with their U
// (pipeline/uncertainty_coverage.h). Not a timing benchmark: it prints the table; run by hand.
//
//   build/bench/uncertainty_coverage [--cases 120] [--seed 1] [--noise-px 0.04] [--spot-draws 16]
//       [--eyes biconic|keratoconus|ablation|irregular] [--jobs 0]
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "model/config.h"
#include "model/device.h"
#include "pipeline/uncertainty_coverage.h"

namespace {

using namespace topocal;

void PrintRows(const char* title, const std::vector<pipeline::CoverageRow>& rows) {
  fmt::print("\n| {} | n | within U (k = 2) | pull rms | largest pull |\n|---|---|---|---|---|\n", title);
  for (const auto& r : rows) {
    fmt::print("| {} | {} | {:.1f} % | {:.2f} | {:.1f} |\n", r.quantity, r.n, 100 * r.covered, r.pull_rms, r.max_abs_pull);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Coverage of the reported U over seeded devices and eyes"};
  pipeline::CoverageOptions o;
  o.cases = 120;
  std::string config_path = TOPOCAL_PAPER_CONFIG;
  std::string device_path = std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json";
  app.add_option("--cases", o.cases, "Seeded cases (device x eye)")->capture_default_str();
  app.add_option("--seed", o.seed, "Seed of every draw")->capture_default_str();
  app.add_option("--noise-px", o.spot_noise_px, "Spot-centre noise, px per axis")->capture_default_str();
  app.add_option("--spot-draws", o.spot_draws, "Monte Carlo draws of the spot noise per case")->capture_default_str();
  app.add_option("--eyes", o.eye_kind, "Only the paper cornea and this kind of the test set")
      ->check(CLI::IsMember({"biconic", "keratoconus", "ablation", "irregular"}));
  app.add_option("--jobs", o.jobs, "Threads (0: every core)")->capture_default_str();
  app.add_option("--config", config_path, "Topographer configuration")->capture_default_str();
  app.add_option("--device", device_path, "The nominal device")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const auto config = model::LoadConfig(config_path);
  const auto nominal = model::LoadDevice(device_path).device;
  const auto r = pipeline::RunUncertaintyCoverage(config, nominal, o);
  fmt::print("{} cases (seed {}, spot noise {} px, {} spot draws), {} failed\n", r.cases, o.seed, o.spot_noise_px,
             o.spot_draws, r.failed);
  for (const auto& f : r.failures) fmt::print("  failed: {}\n", f);
  for (const auto& g : r.measurement) {
    fmt::print("\n{} cases measured with the {}:\n", g.cases, g.surface_model);
    PrintRows("measured quantity", g.rows);
    for (const auto* row : {&g.overall, &g.lower_bounds}) {
      if (row->n == 0) continue;
      fmt::print("| **{}** | {} | {:.1f} % | {:.2f} | {:.1f} |\n", row->quantity, row->n, 100 * row->covered,
                 row->pull_rms, row->max_abs_pull);
    }
  }
  PrintRows("device parameter (pull = error / sd)", r.device);
  return 0;
}
