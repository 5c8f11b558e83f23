#include "pipeline/map_output.h"

#include <cmath>
#include <filesystem>
#include <optional>

#include <fmt/format.h>

#include "model/io.h"
#include "model/parallel.h"
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

// One map to write, on the scale selected for its kind.
struct MapJob {
  const PendingMap* map;
  topo::MapImageOptions image;
  bool csv;
};

// The jobs for one kind of map: its scale selected over the whole set, then each map's image options.
void AddKind(const std::vector<PendingMap>& maps, const topo::MapScaleRequest& request, const MapSetOptions& o,
             bool rings, std::vector<MapJob>* jobs) {
  if (maps.empty()) return;
  std::vector<const topo::GridMap*> grids;
  for (const PendingMap& m : maps) grids.push_back(&m.grid);
  const topo::MapScale scale = topo::SelectMapScale(grids, request);
  for (const PendingMap& m : maps) {
    topo::MapImageOptions mo;
    mo.size_px = o.size_px;
    topo::ApplyMapScale(scale, &mo);
    mo.annotations = m.annotations;
    mo.eye = o.eye;
    if (rings) mo.ring_radii_mm = o.power_ring_radii_mm;
    jobs->push_back({&m, std::move(mo), o.csv});
  }
}

// An entry's maps, one of each kind (elevation and difference may be missing).
struct EntryMaps {
  PendingMap axial, tangential;
  std::optional<PendingMap> elevation, difference;
};

EntryMaps ComputeEntryMaps(const std::string& dir, const AnalysisMapEntry& e) {
  EntryMaps out;
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
  out.axial = {base + "axial_power", PowerGrid(pm, pm.axial_D, fmt::format("Axial power{}", e.label)), notes};
  out.tangential = {base + "tangential_power",
                    PowerGrid(pm, pm.tangential_D, fmt::format("Tangential power{}", e.label)), notes};
  const double r = a.covered_radius_mm;
  // The recovered surface: Psi plus the spline residual in spline mode (topo/reconstruction.h).
  const auto& rec = a.reconstruction;
  const topo::GridMap sag = CartesianGrid(r, "", "\u00b5m", [&](double x, double y) { return rec.Height(x, y) * 1e3; });
  topo::SphereFitResult fit;
  if (auto elev = topo::ElevationAboveBestFitSphere(sag, &fit)) {
    elev->title = fmt::format("Elevation above the best-fit sphere{}", e.label);
    out.elevation = PendingMap{base + "elevation", std::move(*elev), {BestFitSphereLine(fit)}};
  }
  if (e.truth) {
    const model::Biconic b{*e.truth};
    out.difference = PendingMap{base + "height_difference",
                                CartesianGrid(r, fmt::format("Ideal \u2212 recovered height{}", e.label), "\u00b5m",
                                              [&](double x, double y) {
                                                model::SurfaceDerivatives d;
                                                return b.Evaluate(x, y, &d) ? (d.z - rec.Height(x, y)) * 1e3 : NAN;
                                              }),
                                {}};
  }
  return out;
}

}  // namespace

void WriteAnalysisMapSet(const std::string& dir, const std::vector<AnalysisMapEntry>& entries,
                         const MapSetOptions& o) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw model::InputError(fmt::format("{}: cannot create directory: {}", dir, ec.message()));
  // The grids of each entry, then every file, on o.jobs threads: each item writes only its own slot or its own
  // files, and the scales are selected in between over the whole set, so the files do not depend on the threads.
  std::vector<EntryMaps> computed(entries.size());
  model::ParallelFor(entries.size(), o.jobs, [&](size_t k) { computed[k] = ComputeEntryMaps(dir, entries[k]); });
  std::vector<PendingMap> axial, tangential, elevation, difference;
  for (EntryMaps& m : computed) {
    axial.push_back(std::move(m.axial));
    tangential.push_back(std::move(m.tangential));
    if (m.elevation) elevation.push_back(std::move(*m.elevation));
    if (m.difference) difference.push_back(std::move(*m.difference));
  }
  // The sim-K zone drawn on the power maps unless the caller chose other rings.
  MapSetOptions power_options = o;
  if (power_options.power_ring_radii_mm.empty()) {
    const topo::ClinicalOptions clinical;
    power_options.power_ring_radii_mm = {clinical.sim_k_inner_mm, clinical.sim_k_outer_mm};
  }
  std::vector<MapJob> jobs;
  AddKind(axial, o.power, power_options, true, &jobs);
  AddKind(tangential, o.power, power_options, true, &jobs);
  AddKind(elevation, o.elevation, o, false, &jobs);
  AddKind(difference, o.elevation, o, false, &jobs);
  model::ParallelFor(jobs.size(), o.jobs, [&](size_t k) {
    const MapJob& job = jobs[k];
    if (job.csv) topo::WriteMapCsv(job.map->file + ".csv", job.map->grid);
    topo::WriteMapPng(job.map->file + ".png", job.map->grid, job.image);
  });
}

void WriteAnalysisMaps(const std::string& dir, const std::string& prefix, const std::string& label,
                       const topo::Analysis& a, const model::BiconicParams* truth, bool csv, int size_px) {
  MapSetOptions o;
  o.csv = csv;
  o.size_px = size_px;
  WriteAnalysisMapSet(dir, {{prefix, label, &a, truth, {}}}, o);
}

}  // namespace topocal::pipeline
