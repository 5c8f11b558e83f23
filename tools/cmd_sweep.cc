#include <nlohmann/json.hpp>
#include <fmt/format.h>

#include "model/config.h"
#include "model/io.h"
#include "tools/commands.h"
#include "tools/map_output.h"
#include "tools/report_json.h"
#include "topo/sweep.h"

namespace topocal::tools {
namespace {

std::string SweepJson(const topo::SweepResult& r) {
  nlohmann::json j;
  j["spots"] = r.spots;
  j["rows"] = nlohmann::json::array();
  for (const auto& row : r.rows) {
    nlohmann::json jr;
    jr["sigma_per_mm2"] = row.sigma_per_mm2;
    jr["spots_imaged"] = row.spots_imaged;
    jr["image_ellipse"] = {{"a_mm", row.image_ellipse.a_mm},
                           {"b_mm", row.image_ellipse.b_mm},
                           {"beta_deg", row.image_ellipse.beta_deg},
                           {"area_mm2", row.image_ellipse.AreaMm2()},
                           {"area_change_pct", row.area_change_pct}};
    const auto& a = row.analysis;
    jr["surface_fit"] = SurfaceFitJson(a.surface_fit);
    jr["reconstruction"] = ReconstructionJson(a.reconstruction);
    jr["errors"] = ErrorsJson(a);
    j["rows"].push_back(jr);
  }
  j["ideal"] = {{"pv_tangential_D", r.ideal_power.pv_tangential_D}, {"pv_axial_D", r.ideal_power.pv_axial_D}};
  j["timing_ms"] = {{"design", r.timing.design_ms},
                    {"synthesis", r.timing.synthesis_ms},
                    {"analysis", r.timing.analysis_ms},
                    {"total", r.timing.total_ms}};
  return j.dump(2) + "\n";
}

void PrintTableVI(const topo::SweepResult& r) {
  fmt::print("\nTable VI — biconic fitted to the reconstructed surface (rx >= ry, alpha in [0, 180))\n");
  fmt::print("{:>12}  {:>8}  {:>8}  {:>8}  {:>8}  {:>9}  {:>10}\n", "sigma/mm^2", "rx/mm", "ry/mm", "kx", "ky",
             "alpha/deg", "vertex/um");
  for (const auto& row : r.rows) {
    const auto& p = row.analysis.surface_fit.params;
    fmt::print("{:>12.3g}  {:>8.4f}  {:>8.4f}  {:>8.4f}  {:>8.4f}  {:>9.4f}  {:>10.4f}\n", row.sigma_per_mm2, p.rx_mm,
               p.ry_mm, p.kx, p.ky, p.alpha_deg, p.z0_mm * 1e3);
  }
}

void PrintTableVII(const topo::SweepResult& r) {
  fmt::print("\nTable VII — height difference to the true cornea and power-map peak-to-valley (R = {:.2f} mm)\n",
             r.ideal_power.radius_mm);
  fmt::print("{:>12}  {:>10}  {:>10}  {:>10}  {:>10}\n", "sigma/mm^2", "pv/um", "rms/um", "pv_m/D", "pv_a/D");
  for (const auto& row : r.rows) {
    const auto& a = row.analysis;
    fmt::print("{:>12.3g}  {:>10.4f}  {:>10.4f}  {:>10.3f}  {:>10.3f}\n", row.sigma_per_mm2,
               a.errors ? a.errors->pv_um : 0.0, a.errors ? a.errors->rms_um : 0.0, a.power.pv_tangential_D,
               a.power.pv_axial_D);
  }
  fmt::print("{:>12}  {:>10}  {:>10}  {:>10.3f}  {:>10.3f}\n", "ideal", "", "", r.ideal_power.pv_tangential_D,
             r.ideal_power.pv_axial_D);
}

void PrintTableV(const topo::SweepResult& r) {
  fmt::print("Table V — image contour (Fitzgibbon fit to the outer ring), {} spots\n", r.spots);
  fmt::print("{:>12}  {:>9}  {:>9}  {:>9}  {:>10}  {:>8}\n", "sigma/mm^2", "a_e/mm", "b_e/mm", "beta_e/deg",
             "area/mm^2", "E_A/%");
  for (const auto& row : r.rows) {
    fmt::print("{:>12.3g}  {:>9.4f}  {:>9.4f}  {:>9.4f}  {:>10.4f}  {:>8.2f}\n", row.sigma_per_mm2,
               row.image_ellipse.a_mm, row.image_ellipse.b_mm, row.image_ellipse.beta_deg, row.image_ellipse.AreaMm2(),
               row.area_change_pct);
  }
}

}  // namespace

void AddSweepCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("sweep", "Run every sigma of the configuration and print the paper's tables");
  auto config = std::make_shared<std::string>();
  auto json_out = std::make_shared<std::string>();
  auto maps = std::make_shared<std::string>();
  cmd->add_option("--config", *config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--json", *json_out, "Write the sweep as JSON");
  cmd->add_option("--maps", *maps, "Write every sigma's power, height and difference maps (CSV + PNG) here");
  cmd->callback([=] {
    const auto cfg = model::LoadConfig(*config);
    const auto result = topo::RunSweep(cfg);
    for (const auto& f : result.synthesis_failures) {
      fmt::print(stderr, "topocal sweep: spot ({}, {}) not imaged: {}\n", f.id.ring, f.id.index, f.reason);
    }
    PrintTableV(result);
    PrintTableVI(result);
    PrintTableVII(result);
    if (!json_out->empty()) model::WriteFileAtomic(*json_out, SweepJson(result));
    if (!maps->empty()) {
      for (const auto& row : result.rows) {
        WriteAnalysisMaps(*maps, fmt::format("sigma_{:+.3g}_", row.sigma_per_mm2),
                          fmt::format(", sigma = {:.3g} /mm^2", row.sigma_per_mm2), row.analysis, &cfg.cornea);
      }
    }
  });
}

}  // namespace topocal::tools
