// The accuracy tables of issue 18 (docs/reconstruction.md). Not timing benchmarks: they print tables; run by hand.
//
//  * freeform: every cornea of topocal's own test set (model/freeform_test_set.h) imaged through the configured
//    design, reconstructed with the configured settings and compared with the truth against the item-4 targets.
//  * apex: the paper cornea and an oblique one with the apex off the axis (and tilted), exact spots, the biconic
//    fitted in both modes (paper / free-apex): errors of r, k and the apex position.
//
//   build/bench/accuracy_tables freeform [--config data/paper.json] [--surface-model polynomial|spline]
//        [--taylor-degree D] [--noise-px 0.04 --pitch-um 1.12] [--rings N --eta0 E0 --eta E] [--seed S] [--only NAME]
//   build/bench/accuracy_tables apex [--config data/paper.json]
#include <cmath>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "model/config.h"
#include "model/freeform_test_set.h"
#include "model/null_screen.h"
#include "topo/biconic_fit.h"
#include "topo/truth_comparison.h"

namespace {

using namespace topocal;

void ApexTable(const model::Config& base) {
  const struct { const char* name; model::BiconicParams p; } corneas[] = {
      {"paper", {8.35, 7.63, -0.43, -0.25, 17.0, 0, 0, 0}}, {"oblique", {8.7, 7.3, -0.3, 0.1, 95.0, 0, 0, 0}}};
  const struct { double x, y, tx, ty; } offsets[] = {{0.1, 0.0, 0, 0},  {0.0, 0.2, 0, 0},   {0.2, -0.2, 0, 0},
                                                      {-0.3, 0.3, 0, 0}, {0.5, 0.0, 0, 0},   {0.0, 0.0, 3.0, 0},
                                                      {0.3, -0.4, 2.0, -2.2}, {-0.45, 0.2, -2.9, 0.6}};
  fmt::print("{:<8} {:>7} {:>8} | {:>8} {:>8} {:>9} | {:>8} {:>8} {:>9} {:>8}\n", "cornea", "apex/mm", "tilt/deg",
             "paper|dk|", "|dr|/mm", "", "free|dk|", "|dr|/mm", "apex/mm", "tilt/deg");
  for (const auto& c : corneas) {
    for (const auto& o : offsets) {
      model::BiconicParams eye = c.p;
      // (x0, y0) of Eq. 12 are in the rotated frame: place the apex at (o.x, o.y) in the instrument frame.
      const double a = eye.alpha_deg * M_PI / 180.0;
      eye.x0_mm = std::cos(a) * o.x + std::sin(a) * o.y;
      eye.y0_mm = -std::sin(a) * o.x + std::cos(a) * o.y;
      eye.tilt_x_deg = o.tx;
      eye.tilt_y_deg = o.ty;
      {
        model::Biconic focused{eye};
        model::FocusOnAxis(&focused);  // the instrument focuses on the point on its axis
        eye = focused.params;
      }
      const auto truth = topo::CanonicalBiconic(eye);
      const Eigen::Vector3d apex = model::Biconic{eye}.ApexMm();
      double dk[2], dr[2], dapex = 0, dtilt = 0;
      for (int mode = 0; mode < 2; ++mode) {
        model::Config cfg = base;
        cfg.cornea = eye;
        cfg.reconstruction.biconic_fit = mode ? "free-apex" : "paper";
        const auto m = topo::MeasureSimulatedCornea(model::Biconic{eye}, cfg);
        const auto& f = m.analysis.surface_fit;
        dk[mode] = std::max(std::abs(f.params.kx - truth.kx), std::abs(f.params.ky - truth.ky));
        dr[mode] = std::max(std::abs(f.params.rx_mm - truth.rx_mm), std::abs(f.params.ry_mm - truth.ry_mm));
        if (mode) {
          dapex = (f.apex_mm.head<2>() - apex.head<2>()).norm();
          dtilt = std::max(std::abs(f.params.tilt_x_deg - eye.tilt_x_deg), std::abs(f.params.tilt_y_deg - eye.tilt_y_deg));
        }
      }
      fmt::print("{:<8} {:>7.3f} {:>8.2f} | {:>8.4f} {:>8.4f} {:>9} | {:>8.1e} {:>8.1e} {:>9.1e} {:>8.1e}\n", c.name,
                 std::hypot(o.x, o.y), std::hypot(o.tx, o.ty), dk[0], dr[0], "", dk[1], dr[1], dapex, dtilt);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Accuracy tables of issue 18: freeform corneas, eyes off the axis"};
  app.require_subcommand(1);
  auto* freeform = app.add_subcommand("freeform", "topocal's freeform test set against the truth");
  auto* apex_cmd = app.add_subcommand("apex", "eyes off the axis and tilted: paper and free-apex biconic fits");
  std::string config_path = TOPOCAL_PAPER_CONFIG, only;
  int degree = 0, rings = 0, eta0 = 0, eta = 0;
  double noise_px = 0.0, pitch_um = 1.12;
  unsigned seed = 1;
  std::string surface_model;
  double spline_spacing_mm = 0;
  freeform->add_option("--spline-spacing", spline_spacing_mm, "Override reconstruction.spline_spacing_mm");
  for (auto* cmd : {freeform, apex_cmd}) cmd->add_option("--config", config_path, "Topographer configuration")->capture_default_str();
  freeform->add_option("--surface-model", surface_model, "Override reconstruction.surface_model");
  freeform->add_option("--taylor-degree", degree, "Override reconstruction.taylor_degree");
  freeform->add_option("--noise-px", noise_px, "Gaussian spot-centre noise, px (per coordinate)");
  freeform->add_option("--pitch-um", pitch_um, "Pixel pitch that converts --noise-px to mm")->capture_default_str();
  freeform->add_option("--rings", rings, "Override ideal_image.rings_N (denser screen)");
  freeform->add_option("--eta0", eta0, "Override ideal_image.eta0");
  freeform->add_option("--eta", eta, "Override ideal_image.eta");
  freeform->add_option("--seed", seed, "Seed of the noise")->capture_default_str();
  freeform->add_option("--only", only, "One cornea of the set by name");
  CLI11_PARSE(app, argc, argv);
  try {
    auto config = model::LoadConfig(config_path);
    if (apex_cmd->parsed()) {
      ApexTable(config);
      return 0;
    }
    if (!surface_model.empty()) config.reconstruction.surface_model = surface_model;
    if (spline_spacing_mm > 0) config.reconstruction.spline_spacing_mm = spline_spacing_mm;
    if (degree) config.reconstruction.taylor_degree = degree;
    if (rings) config.ideal_image.rings_N = rings;
    if (eta0) config.ideal_image.eta0 = eta0;
    if (eta) config.ideal_image.eta = eta;
    const double noise_mm = noise_px * pitch_um * 1e-3;
    fmt::print("config {}, {} surface, Taylor degree {}, {} spots designed, noise {} px ({:.3g} um)\n", config_path,
               config.reconstruction.surface_model, config.reconstruction.taylor_degree, config.ideal_image.SpotCount(), noise_px, noise_mm * 1e3);
    fmt::print("{:<28} {:>5} {:>6} {:>7} {:>7} {:>7} {:>7} {:>8} {:>7} {:>6} {:>15} {:>7} {:>7} {:>7} {:>6} {:>6}\n", "cornea",
               "spots", "R/mm", "axRMS", "axMax", "tgRMS", "tgMax", "hRMS/um", "dKmax", "dLoc", "cone um t>r",
               "dSteep", "dFlat", "adeq", "corr", "struct");
    for (const auto& c : model::FreeformTestSet()) {
      if (!only.empty() && c.name != only) continue;
      try {
        const auto m = topo::MeasureSimulatedCornea(c.surface, config, noise_mm, seed);
        const auto& e = m.comparison;
        fmt::print("{:<28} {:>5} {:>6.2f} {:>7.3f} {:>7.3f} {:>7.3f} {:>7.3f} {:>8.4f} {:>7.3f} {:>6.3f} {:>7.2f}>{:<7.2f} "
                   "{:>7.3f} {:>7.3f} {:>7.2f} {:>6.2f} {:>6.2f}\n",
                   c.name, m.spots, e.radius_mm, e.axial_rms_D, e.axial_max_D, e.tangential_rms_D, e.tangential_max_D,
                   e.height_rms_um, e.kmax_error_D, e.kmax_location_error_mm, e.cone_height_true_um,
                   e.cone_height_recovered_um, e.steep_k_error_D, e.flat_k_error_D,
                   m.analysis.reconstruction.adequacy_ratio, m.analysis.reconstruction.residual_neighbour_correlation,
                   m.analysis.reconstruction.structured_residual_ratio);
      } catch (const std::runtime_error& ex) {
        fmt::print("{:<28} failed: {}\n", c.name, ex.what());
      }
    }
  } catch (const std::exception& ex) {
    fmt::print(stderr, "freeform_table: {}\n", ex.what());
    return 2;
  }
  return 0;
}
