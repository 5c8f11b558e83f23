#include "pipeline/map_output.h"

#include <cmath>
#include <filesystem>
#include <optional>

#include <fmt/format.h>

#include "model/io.h"
#include "model/surface.h"
#include "topo/map_image.h"

namespace topocal::pipeline {
namespace {

constexpr int kGridSide = 241;  // samples per side of the Cartesian grids (0.05 mm steps over +-6 mm)

topo::GridMap PowerGrid(const topo::PowerMaps& pm, const std::vector<double>& values, const std::string& title) {
  topo::PolarField field;
  field.meridians = pm.meridians;
  for (int k = 0; k < pm.radial_samples; ++k) field.radii_mm.push_back(pm.RhoMm(k));
  field.values = values;
  return topo::ResamplePolar(field, kGridSide, title, "D");
}

template <typename F>
topo::GridMap CartesianGrid(double radius_mm, const std::string& title, const std::string& unit, F value) {
  topo::GridMap g;
  g.x_min_mm = g.y_min_mm = -radius_mm;
  g.x_max_mm = g.y_max_mm = radius_mm;
  g.nx = g.ny = kGridSide;
  g.title = title;
  g.unit = unit;
  g.values.resize(static_cast<size_t>(kGridSide) * kGridSide);
  for (int j = 0; j < kGridSide; ++j) {
    for (int i = 0; i < kGridSide; ++i) {
      const double x = -radius_mm + 2.0 * radius_mm * i / (kGridSide - 1);
      const double y = -radius_mm + 2.0 * radius_mm * j / (kGridSide - 1);
      g.values[static_cast<size_t>(j) * kGridSide + i] = std::hypot(x, y) <= radius_mm ? value(x, y) : NAN;
    }
  }
  return g;
}

// The best-fit sphere under the elevation map's title: its radius, and its centre when it is off the axis.
std::string BestFitSphereLine(const topo::SphereFitResult& fit) {
  constexpr double kOnAxisMm = 0.0005;  // below the printed precision
  if (std::hypot(fit.centre_x_mm, fit.centre_y_mm) < kOnAxisMm) {
    return fmt::format("best-fit sphere R = {:.3f} mm", fit.radius_mm);
  }
  return fmt::format("best-fit sphere R = {:.3f} mm, centre ({:+.3f}, {:+.3f}) mm", fit.radius_mm, fit.centre_x_mm,
                     fit.centre_y_mm);
}

struct PendingMap {
  std::string file;  // without extension
  topo::GridMap grid;
  std::vector<std::string> annotations;
};

void WriteKind(const std::vector<PendingMap>& maps, const topo::MapScaleRequest& request, const MapSetOptions& o,
               bool rings) {
  if (maps.empty()) return;
  std::vector<const topo::GridMap*> grids;
  for (const PendingMap& m : maps) grids.push_back(&m.grid);
  const topo::MapScale scale = topo::SelectMapScale(grids, request);
  for (const PendingMap& m : maps) {
    if (o.csv) topo::WriteMapCsv(m.file + ".csv", m.grid);
    topo::MapImageOptions mo;
    mo.size_px = o.size_px;
    topo::ApplyMapScale(scale, &mo);
    mo.annotations = m.annotations;
    mo.eye = o.eye;
    if (rings) mo.ring_radii_mm = o.power_ring_radii_mm;
    topo::WriteMapPng(m.file + ".png", m.grid, mo);
  }
}

}  // namespace

void WriteAnalysisMapSet(const std::string& dir, const std::vector<AnalysisMapEntry>& entries,
                         const MapSetOptions& o) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw model::InputError(fmt::format("{}: cannot create directory: {}", dir, ec.message()));
  std::vector<PendingMap> axial, tangential, elevation, difference;
  for (const AnalysisMapEntry& e : entries) {
    const std::string base = (std::filesystem::path(dir) / e.prefix).string();
    const topo::Analysis& a = *e.analysis;
    const auto& pm = a.power;
    // The clinical summary under the power maps' titles (topo/clinical_indices.h), unless the caller gave its own.
    std::vector<std::string> notes = e.power_annotations;
    if (notes.empty() && a.clinical_ok) {
      const auto& c = a.clinical;
      notes.push_back(fmt::format("sim-K {:.2f} D @ {:.0f}\u00b0 / {:.2f} D @ {:.0f}\u00b0 (cyl {:.2f} D)", c.steep_k_D,
                                  c.steep_axis_deg, c.flat_k_D, c.flat_axis_deg, c.CylinderD()));
      notes.push_back(fmt::format("Kmax {:.2f} D at ({:+.2f}, {:+.2f}) mm", c.kmax_D, c.kmax_at_mm.x(), c.kmax_at_mm.y()));
    }
    axial.push_back({base + "axial_power", PowerGrid(pm, pm.axial_D, fmt::format("Axial power{}", e.label)), notes});
    tangential.push_back({base + "tangential_power",
                          PowerGrid(pm, pm.tangential_D, fmt::format("Tangential power{}", e.label)), notes});
    const double r = a.covered_radius_mm;
    // The recovered surface: Psi plus the spline residual in spline mode (topo/reconstruction.h).
    const auto& rec = a.reconstruction;
    const topo::GridMap sag = CartesianGrid(r, "", "\u00b5m", [&](double x, double y) { return rec.Height(x, y) * 1e3; });
    topo::SphereFitResult fit;
    if (auto elev = topo::ElevationAboveBestFitSphere(sag, &fit)) {
      elev->title = fmt::format("Elevation above the best-fit sphere{}", e.label);
      elevation.push_back({base + "elevation", std::move(*elev),
                           {BestFitSphereLine(fit)}});
    }
    if (e.truth) {
      const model::Biconic b{*e.truth};
      difference.push_back(
          {base + "height_difference",
           CartesianGrid(r, fmt::format("Ideal \u2212 recovered height{}", e.label), "\u00b5m",
                         [&](double x, double y) {
                           model::SurfaceDerivatives d;
                           return b.Evaluate(x, y, &d) ? (d.z - rec.Height(x, y)) * 1e3 : NAN;
                         }),
           {}});
    }
  }
  // The sim-K zone drawn on the power maps unless the caller chose other rings.
  MapSetOptions power_options = o;
  if (power_options.power_ring_radii_mm.empty()) {
    const topo::ClinicalOptions clinical;
    power_options.power_ring_radii_mm = {clinical.sim_k_inner_mm, clinical.sim_k_outer_mm};
  }
  WriteKind(axial, o.power, power_options, true);
  WriteKind(tangential, o.power, power_options, true);
  WriteKind(elevation, o.elevation, o, false);
  WriteKind(difference, o.elevation, o, false);
}

void WriteAnalysisMaps(const std::string& dir, const std::string& prefix, const std::string& label,
                       const topo::Analysis& a, const model::BiconicParams* truth, bool csv, int size_px) {
  MapSetOptions o;
  o.csv = csv;
  o.size_px = size_px;
  WriteAnalysisMapSet(dir, {{prefix, label, &a, truth, {}}}, o);
}

}  // namespace topocal::pipeline
