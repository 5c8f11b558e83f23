#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "model/config.h"
#include "model/io.h"
#include "model/null_screen.h"
#include "tools/commands.h"
#include "tools/csv.h"
#include "tools/map_output.h"
#include "tools/report_json.h"
#include "topo/analysis.h"

namespace topocal::tools {
namespace {

void PrintAnalysis(const topo::Analysis& a) {
  const auto& r = a.reconstruction;
  const auto& f = a.surface_fit;
  const auto& p = f.params;
  fmt::print("reconstruction: {}\n", r.message);
  if (!r.unmatched.empty()) fmt::print("spots not in the design (ignored): {}\n", r.unmatched.size());
  fmt::print("biconic fit ({} points, rms {:.4f} um):\n", f.points, f.rms_residual_um);
  const auto& sd = f.stddev;
  fmt::print("  rx = {:.4f} +- {:.4f} mm   ry = {:.4f} +- {:.4f} mm\n", p.rx_mm, sd.rx_mm, p.ry_mm, sd.ry_mm);
  fmt::print("  kx = {:.4f} +- {:.4f}      ky = {:.4f} +- {:.4f}\n", p.kx, sd.kx, p.ky, sd.ky);
  fmt::print("  alpha = {:.4f} +- {:.4f} deg   vertex = {:.4f} +- {:.4f} um\n", p.alpha_deg, sd.alpha_deg,
             p.z0_mm * 1e3, sd.z0_mm * 1e3);
  fmt::print("power maps (R = {:.2f} mm, points reach {:.2f} mm): pv tangential {:.3f} D, pv axial {:.3f} D\n",
             a.power.radius_mm, a.covered_radius_mm, a.power.pv_tangential_D, a.power.pv_axial_D);
  if (a.errors) fmt::print("against the configured cornea: pv {:.4f} um, rms {:.4f} um\n", a.errors->pv_um, a.errors->rms_um);
}

}  // namespace

void AddReconstructCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("reconstruct", "Recover the cornea from spot positions: surface, biconic fit, maps");
  auto config = std::make_shared<std::string>();
  auto spots = std::make_shared<std::string>();
  auto json_out = std::make_shared<std::string>();
  auto maps = std::make_shared<std::string>();
  auto truth = std::make_shared<bool>(false);
  cmd->add_option("--config", *config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--spots", *spots, "Spots CSV (ring,index,x_mm,y_mm on the detection plane)")->required();
  cmd->add_option("--json", *json_out, "Write the result as JSON");
  cmd->add_option("--maps", *maps, "Write power and height maps (CSV + PNG) into this directory");
  cmd->add_flag("--truth", *truth, "Compare with the configuration's cornea (pv and rms of the height difference)");
  cmd->callback([=] {
    const auto cfg = model::LoadConfig(*config);
    const auto rows = ReadSpotsCsv(*spots);
    std::vector<topo::MeasuredSpot> measured;
    measured.reserve(rows.size());
    for (const auto& r : rows) measured.push_back({r.id, Eigen::Vector2d(r.x_mm, r.y_mm)});
    const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
    const auto analysis = topo::AnalyzeSpots(measured, design.targets, cfg, *truth ? &cfg.cornea : nullptr);
    PrintAnalysis(analysis);
    if (!json_out->empty()) {
      nlohmann::json j;
      j["spots_read"] = rows.size();
      j["reconstruction"] = ReconstructionJson(analysis.reconstruction);
      j["polynomial"] = PolynomialJson(analysis.reconstruction.surface);
      j["surface_fit"] = SurfaceFitJson(analysis.surface_fit);
      j["power"] = {{"pv_tangential_D", analysis.power.pv_tangential_D}, {"pv_axial_D", analysis.power.pv_axial_D},
                    {"map_radius_mm", analysis.power.radius_mm}, {"covered_radius_mm", analysis.covered_radius_mm}};
      if (*truth) j["errors"] = ErrorsJson(analysis);
      model::WriteFileAtomic(*json_out, j.dump(2) + "\n");
    }
    if (!maps->empty()) WriteAnalysisMaps(*maps, "", "", analysis, *truth ? &cfg.cornea : nullptr);
  });
}

}  // namespace topocal::tools
