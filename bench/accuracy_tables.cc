// The accuracy tables of freeform corneas and eyes off the axis (docs/reconstruction.md). Not timing benchmarks:
// they print tables; run by hand.
//
//  * freeform: every cornea of topocal's own test set (model/freeform_test_set.h) imaged through the configured
//    design, reconstructed with the configured settings and compared with the truth against the accuracy targets.
//  * apex: the paper cornea and an oblique one with the apex off the axis (and tilted), exact spots, the biconic
//    fitted in both modes (paper / free-apex): errors of r, k and the apex position.
//
//   build/bench/accuracy_tables freeform [--config data/paper.json] [--surface-model polynomial|spline]
//        [--taylor-degree D] [--noise-px 0.04 --pitch-um 1.12] [--rings N --eta0 E0 --eta E] [--seed S] [--only NAME]
//   build/bench/accuracy_tables apex [--config data/paper.json]
//   build/bench/accuracy_tables diagnose [--only NAME] [--spline-spacing H]   (the ablations by default)
#include <cmath>
#include <map>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "model/config.h"
#include "model/freeform_test_set.h"
#include "model/null_screen.h"
#include "topo/biconic_fit.h"
#include "topo/bspline_surface.h"
#include "topo/power_map.h"
#include "topo/taylor_polynomial.h"
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


// Where the spline's error on a cornea comes from (docs/reconstruction.md, "Where the ablations' error comes
// from"): the same representation (polynomial + P-spline residual) fitted to the TRUE slopes at the true incidence
// points (no reflection model, no iteration), at the REML lambda and at lambda x 1e-2 / x 1e2, on a dense grid of
// true slopes, and at other knot spacings, each compared with the truth like the reconstruction; tangential RMS by
// radial band besides.
struct ShapeErrors {
  double axial_rms = 0, tangential_rms = 0, height_rms_um = 0, lambda = 0;
  std::vector<double> band_tangential_rms;  // per 0.5 mm band
};

constexpr double kBandMm = 0.5;

ShapeErrors ErrorsOf(const topo::SurfaceEvaluator& recovered, const model::Surface& truth, double radius_mm,
                     const std::vector<Eigen::Vector2d>& points, const model::ReconstructionSettings& settings) {
  // Both reduced to their shape: tangent plane at the origin removed.
  const auto shape_of = [](const topo::SurfaceEvaluator& f) {
    model::SurfaceDerivatives o;
    f(0.0, 0.0, &o);
    return topo::SurfaceEvaluator([f, o](double x, double y, model::SurfaceDerivatives* d) {
      if (!f(x, y, d)) return false;
      d->z -= o.z + o.zx * x + o.zy * y;
      d->zx -= o.zx;
      d->zy -= o.zy;
      return true;
    });
  };
  const topo::SurfaceEvaluator truth_eval = [&](double x, double y, model::SurfaceDerivatives* d) {
    return model::EvaluateSurface(truth, x, y, d);
  };
  topo::PowerMaps got, want;
  const auto options = topo::PowerMapOptionsFrom(settings);
  if (!topo::ComputePowerMaps(shape_of(recovered), options, &got) ||
      !topo::ComputePowerMaps(shape_of(truth_eval), options, &want)) {
    throw std::runtime_error("power maps failed");
  }
  ShapeErrors e;
  const int bands = static_cast<int>(std::ceil(radius_mm / kBandMm));
  std::vector<double> bs(bands, 0.0);
  std::vector<int> bn(bands, 0);
  double sa = 0, st = 0;
  int n = 0;
  for (int j = 0; j < want.meridians; ++j) {
    for (int k = 0; k < want.radial_samples && want.RhoMm(k) <= radius_mm; ++k) {
      const size_t i = static_cast<size_t>(j) * want.radial_samples + k;
      const double ea = got.axial_D[i] - want.axial_D[i], et = got.tangential_D[i] - want.tangential_D[i];
      sa += ea * ea;
      st += et * et;
      ++n;
      const int b = std::min(bands - 1, static_cast<int>(want.RhoMm(k) / kBandMm));
      bs[b] += et * et;
      ++bn[b];
    }
  }
  e.axial_rms = std::sqrt(sa / n);
  e.tangential_rms = std::sqrt(st / n);
  for (int b = 0; b < bands; ++b) e.band_tangential_rms.push_back(bn[b] ? std::sqrt(bs[b] / bn[b]) : 0.0);
  double s = 0, s2 = 0;
  for (const auto& p : points) {
    model::SurfaceDerivatives t, r;
    model::EvaluateSurface(truth, p.x(), p.y(), &t);
    recovered(p.x(), p.y(), &r);
    const double d = (t.z - r.z) * 1e3;
    s += d;
    s2 += d * d;
  }
  const double mean = s / points.size();
  e.height_rms_um = std::sqrt(std::max(0.0, s2 / points.size() - mean * mean));
  return e;
}

// Polynomial (as the reconstruction normalises it) plus a spline residual fitted to the given slopes; lambda < 0:
// REML, then lambda_factor times the REML lambda when it is not 1.
ShapeErrors FitTrueSlopes(const model::Surface& truth, const std::vector<Eigen::Vector2d>& at,
                          const std::vector<Eigen::Vector2d>& eval_points, double norm_radius, double spacing_mm,
                          double lambda_factor, double radius_mm, const model::ReconstructionSettings& settings,
                          int penalty_order = 3) {
  std::vector<Eigen::Vector2d> slopes;
  for (const auto& p : at) {
    model::SurfaceDerivatives d;
    model::EvaluateSurface(truth, p.x(), p.y(), &d);
    slopes.emplace_back(d.zx, d.zy);
  }
  topo::TaylorPolynomial psi(settings.taylor_degree, norm_radius);
  topo::GradientFitter fitter;
  if (!fitter.Fit(at, slopes, 0.0, &psi).ok) throw std::runtime_error("polynomial fit failed");
  std::vector<Eigen::Vector2d> residual(at.size());
  for (size_t i = 0; i < at.size(); ++i) {
    double z, zx, zy;
    psi.ValueAndGradient(at[i].x(), at[i].y(), &z, &zx, &zy);
    residual[i] = slopes[i] - Eigen::Vector2d(zx, zy);
  }
  topo::BSplineSurface spline(norm_radius, spacing_mm);
  topo::SplineFitOptions so;
  so.penalty_order = penalty_order;
  topo::SplineFit f = topo::FitSplineToSlopes(at, residual, -1.0, so, &spline);
  if (lambda_factor != 1.0) f = topo::FitSplineToSlopes(at, residual, f.lambda * lambda_factor, so, &spline);
  if (!f.ok) throw std::runtime_error("spline fit failed");
  const topo::SurfaceEvaluator eval = [&](double x, double y, model::SurfaceDerivatives* d) {
    psi.Derivatives(x, y, &d->z, &d->zx, &d->zy, &d->zxx, &d->zxy, &d->zyy);
    double s, sx, sy, sxx, sxy, syy;
    spline.Derivatives(x, y, &s, &sx, &sy, &sxx, &sxy, &syy);
    d->z += s, d->zx += sx, d->zy += sy, d->zxx += sxx, d->zxy += sxy, d->zyy += syy;
    return true;
  };
  ShapeErrors e = ErrorsOf(eval, truth, radius_mm, eval_points, settings);
  e.lambda = f.lambda;
  return e;
}

void PrintRow(const std::string& what, const ShapeErrors& e) {
  fmt::print("  {:<44} {:>7.3f} {:>7.3f} {:>8.4f} {:>9.2e} |", what, e.axial_rms, e.tangential_rms, e.height_rms_um,
             e.lambda);
  for (double b : e.band_tangential_rms) fmt::print(" {:>5.2f}", b);
  fmt::print("\n");
}

void DiagnoseTable(const model::Config& config, const std::string& only) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  fmt::print("  {:<44} {:>7} {:>7} {:>8} {:>9} | tangential RMS (D) per {} mm band from the centre\n", "", "axRMS",
             "tgRMS", "hRMS/um", "lambda", kBandMm);
  for (const auto& c : model::FreeformTestSet()) {
    if (only.empty() ? c.kind != "ablation" : c.name != only) continue;
    const model::Surface truth = c.surface;
    const auto image = model::SynthesizeImage(truth, model::Topographer{config.topographer}, design.targets);
    std::vector<model::PlaneSpot> spots;
    std::vector<Eigen::Vector2d> true_points;
    for (const auto& s : image.spots) {
      spots.push_back({s.id, s.position_mm});
      true_points.push_back(s.on_surface_mm.head<2>());
    }
    {
      std::map<int, std::pair<double, int>> ring_radius;
      for (const auto& sp : image.spots) {
        auto& rr = ring_radius[sp.id.ring];
        rr.first += sp.on_surface_mm.head<2>().norm();
        ++rr.second;
      }
      fmt::print("ring radii (mm):");
      for (const auto& [ring, rr] : ring_radius) fmt::print(" {:.2f}", rr.first / rr.second);
      fmt::print("\n");
    }
    const auto a = topo::AnalyzeSpots(spots, design.targets, config, nullptr);
    const auto& r = a.reconstruction;
    const double radius = std::min(a.supported_radius_mm, a.power.radius_mm);
    std::vector<Eigen::Vector2d> rec_points;
    double moved = 0;
    for (size_t i = 0; i < r.points.size(); ++i) {
      rec_points.push_back(r.points[i].point_mm.head<2>());
      moved = std::max(moved, (r.points[i].point_mm - image.spots[i].on_surface_mm).norm());
    }
    fmt::print("{} (supported radius {:.2f} mm, norm radius {:.1f} mm; incidence points off by <= {:.2g} um)\n", c.name,
               radius, r.surface.norm_radius_mm(), moved * 1e3);
    const topo::SurfaceEvaluator rec = [&](double x, double y, model::SurfaceDerivatives* d) {
      r.Derivatives(x, y, d);
      return true;
    };
    ShapeErrors e = ErrorsOf(rec, truth, radius, rec_points, config.reconstruction);
    e.lambda = r.spline_lambda;
    PrintRow("reconstruction", e);
    const double nr = r.surface.norm_radius_mm(), h = config.reconstruction.spline_spacing_mm;
    const auto& s = config.reconstruction;
    PrintRow("true slopes at the true points, REML", FitTrueSlopes(truth, true_points, true_points, nr, h, 1.0, radius, s));
    PrintRow("  lambda x 1e-2", FitTrueSlopes(truth, true_points, true_points, nr, h, 1e-2, radius, s));
    PrintRow("  lambda x 1e-4", FitTrueSlopes(truth, true_points, true_points, nr, h, 1e-4, radius, s));
    PrintRow("  lambda x 1e2", FitTrueSlopes(truth, true_points, true_points, nr, h, 1e2, radius, s));
    for (double hh : {0.25, 0.2, 0.5}) {
      PrintRow(fmt::format("  knots every {} mm, REML", hh), FitTrueSlopes(truth, true_points, true_points, nr, hh, 1.0, radius, s));
    }
    for (int order : {2, 4}) {
      for (double hh : {0.33, 0.25}) {
        PrintRow(fmt::format("  penalty order {}, knots {} mm", order, hh),
                 FitTrueSlopes(truth, true_points, true_points, nr, hh, 1.0, radius, s, order));
      }
    }
    std::vector<Eigen::Vector2d> grid;
    for (double y = -nr; y <= nr; y += 0.1)
      for (double x = -nr; x <= nr; x += 0.1)
        if (std::hypot(x, y) <= nr) grid.emplace_back(x, y);
    PrintRow(fmt::format("true slopes on a 0.1 mm grid ({}), REML", grid.size()),
             FitTrueSlopes(truth, grid, true_points, nr, h, 1.0, radius, s));
    PrintRow("  knots every 0.2 mm", FitTrueSlopes(truth, grid, true_points, nr, 0.2, 1.0, radius, s));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Accuracy tables: freeform corneas, eyes off the axis"};
  app.require_subcommand(1);
  auto* freeform = app.add_subcommand("freeform", "topocal's freeform test set against the truth");
  auto* apex_cmd = app.add_subcommand("apex", "eyes off the axis and tilted: paper and free-apex biconic fits");
  auto* diagnose = app.add_subcommand("diagnose", "where the spline's error comes from (ablations, or --only)");
  std::string config_path = TOPOCAL_PAPER_CONFIG, only;
  int degree = 0, rings = 0, eta0 = 0, eta = 0;
  double noise_px = 0.0, pitch_um = 1.12;
  unsigned seed = 1;
  std::string surface_model;
  double spline_spacing_mm = 0;
  freeform->add_option("--spline-spacing", spline_spacing_mm, "Override reconstruction.spline_spacing_mm");
  diagnose->add_option("--only", only, "One cornea of the set by name");
  diagnose->add_option("--spline-spacing", spline_spacing_mm, "Override reconstruction.spline_spacing_mm");
  for (auto* cmd : {freeform, apex_cmd, diagnose}) cmd->add_option("--config", config_path, "Topographer configuration")->capture_default_str();
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
    if (diagnose->parsed()) {
      config.reconstruction.surface_model = "spline";
      DiagnoseTable(config, only);
      return 0;
    }
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
