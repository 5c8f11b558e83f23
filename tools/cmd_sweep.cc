#include <nlohmann/json.hpp>
#include <fmt/format.h>

#include "model/config.h"
#include "model/io.h"
#include "tools/commands.h"
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
    j["rows"].push_back(jr);
  }
  j["timing_ms"] = {{"design", r.timing.design_ms}, {"synthesis", r.timing.synthesis_ms}, {"total", r.timing.total_ms}};
  return j.dump(2) + "\n";
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
  cmd->add_option("--config", *config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--json", *json_out, "Write the sweep as JSON");
  cmd->callback([=] {
    const auto cfg = model::LoadConfig(*config);
    const auto result = topo::RunSweep(cfg);
    for (const auto& f : result.synthesis_failures) {
      fmt::print(stderr, "topocal sweep: spot ({}, {}) not imaged: {}\n", f.id.ring, f.id.index, f.reason);
    }
    PrintTableV(result);
    if (!json_out->empty()) model::WriteFileAtomic(*json_out, SweepJson(result));
  });
}

}  // namespace topocal::tools
