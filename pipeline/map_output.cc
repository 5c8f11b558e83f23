#include "pipeline/map_output.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <utility>

#include "model/surface.h"
#include "plot/map_image.h"
#include "plot/map_page.h"
#include "topo/map_grid.h"
#include "topo/sphere_fit.h"
#include "util/io.h"
#include "util/parallel.h"

namespace topocal::pipeline {
namespace {

constexpr int kGridSide = 241;
// The sim-K axes are drawn when the cylinder shows at the printed resolution (0.01 D).
constexpr double kMinDrawnCylinderD = 0.005;  // samples per side of the Cartesian grids (0.05 mm steps over +-6 mm)

model::GridMap PowerGrid(const topo::PowerMaps& pm, const std::vector<double>& values, const std::string& title) {
  topo::PolarField field;
  field.meridians = pm.meridians;
  for (int k = 0; k < pm.radial_samples; ++k) field.radii_mm.push_back(pm.RhoMm(k));
  field.values = values;
  return topo::ResamplePolar(field, kGridSide, title, "D");
}

template <typename F>
model::GridMap CartesianGrid(double radius_mm, const std::string& title, const std::string& unit, F value) {
  model::GridMap g;
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
std::string BestFitSphereLine(double radius_mm, const Eigen::Vector3d& centre_mm) {
  constexpr double kOnAxisMm = 0.0005;  // below the printed precision
  if (std::hypot(centre_mm.x(), centre_mm.y()) < kOnAxisMm) {
    return fmt::format("best-fit sphere R = {:.3f} mm", radius_mm);
  }
  return fmt::format("best-fit sphere R = {:.3f} mm, centre ({:+.3f}, {:+.3f}) mm", radius_mm, centre_mm.x(),
                     centre_mm.y());
}

// What the overlays of a map are, in words, for its legend (plot/map_image.h draws them).
std::string SupportLegend(double supported_radius_mm) {
  return fmt::format("dashed circle: data in every direction to {:.2f} mm; hatched beyond: extrapolated",
                     supported_radius_mm);
}

}  // namespace

AnalysisGrids AnalysisGridsOf(const topo::Analysis& a) {
  AnalysisGrids g;
  const auto& pm = a.power;
  g.axial_D = PowerGrid(pm, pm.axial_D, "Axial power");
  g.tangential_D = PowerGrid(pm, pm.tangential_D, "Tangential power");
  // The recovered surface: Psi plus the spline residual in spline mode (topo/reconstruction.h).
  const auto& rec = a.reconstruction;
  const model::GridMap sag =
      CartesianGrid(a.covered_radius_mm, "", "\u00b5m", [&](double x, double y) { return rec.Height(x, y) * 1e3; });
  // Elevation above the clinical indices' best-fit sphere (one fit, topo/clinical_indices.h); without the indices
  // (data short of the sim-K ring) the same sag fit (topo/sphere_fit.h) over the whole map.
  if (a.clinical_ok) {
    g.best_fit_sphere.ok = true;
    g.best_fit_sphere.centre_mm = a.clinical.bfs_centre_mm;
    g.best_fit_sphere.radius_mm = a.clinical.bfs_radius_mm;
  } else {
    std::vector<Eigen::Vector3d> points;
    for (int j = 0; j < sag.ny; ++j) {
      for (int i = 0; i < sag.nx; ++i) {
        const double x = sag.x_min_mm + i * (sag.x_max_mm - sag.x_min_mm) / (sag.nx - 1);
        const double y = sag.y_min_mm + j * (sag.y_max_mm - sag.y_min_mm) / (sag.ny - 1);
        if (std::isfinite(sag.At(i, j))) points.emplace_back(x, y, sag.At(i, j) * 1e-3);
      }
    }
    topo::SphereFitOptions so;
    so.residual = topo::SphereResidual::kSag;
    so.stddev = false;
    g.best_fit_sphere = topo::FitSphere(points, so);
  }
  if (g.best_fit_sphere.ok) {
    g.elevation_um = topo::ElevationAboveSphere(sag, g.best_fit_sphere.AsSurface());
    g.elevation_um->title = "Elevation above the best-fit sphere";
  }
  return g;
}

namespace {

struct PendingMap {
  PendingMap() = default;
  PendingMap(std::string file_in, model::GridMap grid_in, std::vector<std::string> annotations_in = {})
      : file(std::move(file_in)), grid(std::move(grid_in)), annotations(std::move(annotations_in)) {}
  std::string file;  // without extension
  model::GridMap grid;
  std::vector<std::string> annotations;
  // Clinical overlays (plot::MapImageOptions): markers, sim-K axes, supported circle, legend.
  std::vector<plot::MapMarker> markers;
  std::vector<plot::MapAxis> axes;
  double supported_radius_mm = 0;
  std::vector<std::string> legend;
};

// One map to write, on the scale selected for its kind.
struct MapJob {
  const PendingMap* map;
  plot::MapImageOptions image;
  bool csv;
};

// The jobs for one kind of map: its scale selected over the whole set, then each map's image options.
void AddKind(const std::vector<PendingMap>& maps, const plot::MapScaleRequest& request, const MapSetOptions& o,
             bool rings, std::vector<MapJob>* jobs) {
  if (maps.empty()) return;
  std::vector<const model::GridMap*> grids;
  for (const PendingMap& m : maps) grids.push_back(&m.grid);
  const plot::MapScale scale = plot::SelectMapScale(grids, request);
  for (const PendingMap& m : maps) {
    plot::MapImageOptions mo;
    mo.size_px = o.size_px;
    plot::ApplyMapScale(scale, &mo);
    mo.annotations = m.annotations;
    mo.markers = m.markers;
    mo.axes = m.axes;
    mo.supported_radius_mm = m.supported_radius_mm;
    mo.legend = m.legend;
    mo.eye = o.eye;
    if (rings) {
      mo.ring_radii_mm = o.power_ring_radii_mm;
      std::vector<std::string> radii;
      for (const double r : o.power_ring_radii_mm) radii.push_back(fmt::format("{:g}", r));
      mo.legend.push_back(fmt::format("dashed rings at {} mm{}", fmt::join(radii, " and "),
                                      o.rings_are_sim_k_zone ? ": the sim-K zone" : ""));
    }
    jobs->push_back({&m, std::move(mo), o.csv});
  }
}

// An entry's maps, one of each kind (elevation and difference may be missing).
struct EntryMaps {
  PendingMap axial, tangential;
  std::optional<PendingMap> elevation, difference, axial_uncertainty;
};

// The axial-power uncertainty maps' scale: fixed colours (a colour is the same U on every unit and eye), 0.05 D
// steps to 0.5 D — a fifth of the 0.25 D step a clinician acts on, to twice it — widened by whole steps to hold more.
plot::MapScaleRequest UncertaintyScale() {
  plot::MapScaleRequest r;
  r.kind = plot::MapScaleKind::kAbsolute;
  r.step = 0.05;
  r.low = 0.0;
  r.high = 0.5;
  r.widen_to_data = true;
  return r;
}

// A peak whose twin lies within U (MarkAmbiguousPeaks): named, not placed.
constexpr const char* kUndeterminedLocation = "a location not determined (a second peak lies within U)";

// The elevation above the best-fit sphere, its peak marked.
PendingMap ElevationMap(const std::string& base, const AnalysisMapEntry& e, AnalysisGrids* grids) {
  const topo::Analysis& a = *e.analysis;
  PendingMap elev{base + "elevation", std::move(*grids->elevation_um),
                  {BestFitSphereLine(grids->best_fit_sphere.radius_mm, grids->best_fit_sphere.centre_mm)}};
  elev.grid.title = fmt::format("Elevation above the best-fit sphere{}", e.label);
  elev.supported_radius_mm = a.supported_radius_mm;
  if (a.clinical_ok) {
    const auto& c = a.clinical;
    if (e.elevation_peak_location_determined) {
      elev.markers.push_back({c.elevation_peak_at_mm.x(), c.elevation_peak_at_mm.y()});
      elev.legend.push_back(fmt::format(
          "magenta dot: elevation peak {:.2f} \u00b5m at ({:+.2f}, {:+.2f}) mm (sphere fitted within {:.2f} mm)",
          c.elevation_peak_um, c.elevation_peak_at_mm.x(), c.elevation_peak_at_mm.y(), c.bfs_zone_radius_mm));
    } else {
      elev.legend.push_back(fmt::format("elevation peak {:.2f} \u00b5m at {} (sphere fitted within {:.2f} mm)",
                                        c.elevation_peak_um, kUndeterminedLocation, c.bfs_zone_radius_mm));
    }
  }
  elev.legend.push_back(SupportLegend(a.supported_radius_mm));
  return elev;
}

// The U (k = 2) of the axial map, beside it.
PendingMap UncertaintyMap(const std::string& base, const AnalysisMapEntry& e, double supported_radius_mm) {
  PendingMap u(base + "axial_uncertainty",
               PowerGrid(e.analysis->power, *e.axial_expanded_D, fmt::format("U of the axial power (k = 2){}", e.label)));
  u.supported_radius_mm = supported_radius_mm;
  u.legend.push_back("expanded uncertainty U (k = 2) of the axial map at each point: device covariance and the "
                     "image's spot noise");
  u.legend.push_back(SupportLegend(supported_radius_mm));
  return u;
}

}  // namespace

std::vector<std::string> ClinicalSummaryLines(const topo::Analysis& a, bool kmax_location_determined,
                                              bool elevation_peak_location_determined) {
  if (!a.clinical_ok) return {"no clinical indices: " + a.clinical_message};
  const auto& c = a.clinical;
  return {c.CylinderD() >= kMinDrawnCylinderD
              ? fmt::format("sim-K {:.2f} D @ {:.0f}\u00b0 / {:.2f} D @ {:.0f}\u00b0 (cyl {:.2f} D)", c.steep_k_D,
                            c.steep_axis_deg, c.flat_k_D, c.flat_axis_deg, c.CylinderD())
              : fmt::format("sim-K {:.2f} D / {:.2f} D (cyl {:.2f} D: no axis)", c.steep_k_D, c.flat_k_D, c.CylinderD()),
          kmax_location_determined
              ? fmt::format("Kmax {:.2f} D at ({:+.2f}, {:+.2f}) mm", c.kmax_D, c.kmax_at_mm.x(), c.kmax_at_mm.y())
              : fmt::format("Kmax {:.2f} D at {}", c.kmax_D, kUndeterminedLocation),
          elevation_peak_location_determined
              ? fmt::format("elevation peak {:.2f} \u00b5m at ({:+.2f}, {:+.2f}) mm", c.elevation_peak_um,
                            c.elevation_peak_at_mm.x(), c.elevation_peak_at_mm.y())
              : fmt::format("elevation peak {:.2f} \u00b5m at {}", c.elevation_peak_um, kUndeterminedLocation),
          fmt::format("best-fit sphere R = {:.3f} mm (fitted within {:.2f} mm)", c.bfs_radius_mm, c.bfs_zone_radius_mm)};
}

namespace {

EntryMaps ComputeEntryMaps(const std::string& dir, const AnalysisMapEntry& e) {
  EntryMaps out;
  const std::string base = (std::filesystem::path(dir) / e.prefix).string();
  const topo::Analysis& a = *e.analysis;
  // The clinical summary under the power maps' titles (topo/clinical_indices.h), unless the caller gave its own.
  std::vector<std::string> notes = e.power_annotations;
  if (notes.empty() && a.clinical_ok) {
    notes = ClinicalSummaryLines(a, e.kmax_location_determined);
    notes.resize(2);  // sim-K and Kmax
  }
  // Overlays from the clinical indices: the sim-K axes across the supported disc on both
  // power maps, Kmax (an axial quantity) on the axial map, the elevation peak on the elevation map, and on every
  // map the supported circle with the extrapolated area hatched.
  const double supported = a.supported_radius_mm;
  std::vector<plot::MapAxis> sim_k_axes;
  std::string axes_legend;
  if (a.clinical_ok && a.clinical.CylinderD() >= kMinDrawnCylinderD) {
    const auto& c = a.clinical;
    sim_k_axes = {{c.steep_axis_deg, supported, false}, {c.flat_axis_deg, supported, true}};
    axes_legend = fmt::format("solid line: steep sim-K axis {:.0f}\u00b0 ({:.2f} D); dashed: flat {:.0f}\u00b0 ({:.2f} D)",
                              c.steep_axis_deg, c.steep_k_D, c.flat_axis_deg, c.flat_k_D);
  } else if (a.clinical_ok) {  // a sphere's axes are noise: none drawn, and the legend says why
    axes_legend = fmt::format("no sim-K axes: cylinder {:.2f} D", a.clinical.CylinderD());
  }
  AnalysisGrids grids = AnalysisGridsOf(a);
  grids.axial_D.title = fmt::format("Axial power{}", e.label);
  grids.tangential_D.title = fmt::format("Tangential power{}", e.label);
  PendingMap axial_map{base + "axial_power", std::move(grids.axial_D), notes};
  PendingMap tangential_map{base + "tangential_power", std::move(grids.tangential_D), notes};
  for (PendingMap* m : {&axial_map, &tangential_map}) {
    m->axes = sim_k_axes;
    m->supported_radius_mm = supported;
    if (!axes_legend.empty()) m->legend.push_back(axes_legend);
    m->legend.push_back(SupportLegend(supported));
  }
  if (a.clinical_ok && e.kmax_location_determined) {
    const auto& c = a.clinical;
    axial_map.markers.push_back({c.kmax_at_mm.x(), c.kmax_at_mm.y()});
    axial_map.legend.insert(axial_map.legend.begin(),
                            fmt::format("magenta dot: Kmax {:.2f} D at ({:+.2f}, {:+.2f}) mm", c.kmax_D,
                                        c.kmax_at_mm.x(), c.kmax_at_mm.y()));
  }
  out.axial = std::move(axial_map);
  out.tangential = std::move(tangential_map);
  const double r = a.covered_radius_mm;
  const auto& rec = a.reconstruction;
  if (grids.elevation_um) out.elevation = ElevationMap(base, e, &grids);
  if (e.axial_expanded_D && e.axial_expanded_D->size() == a.power.axial_D.size()) {
    out.axial_uncertainty = UncertaintyMap(base, e, supported);
  }
  if (e.truth) {
    const model::Surface truth = model::Biconic{*e.truth};
    PendingMap diff(
        base + "height_difference",
        CartesianGrid(r, fmt::format("Ideal \u2212 recovered height{}", e.label), "\u00b5m", [&](double x, double y) {
          const auto delta = topo::HeightDifferenceMm(truth, x, y, rec.Height(x, y));
          return delta ? *delta * 1e3 : NAN;  // Eq. 26
        }));
    diff.supported_radius_mm = supported;
    diff.legend.push_back(SupportLegend(supported));
    out.difference = std::move(diff);
  }
  return out;
}

// Each entry's overview page (MapSetOptions::overview): its axial, tangential and elevation maps as drawn, at half
// size, with the clinical numbers and the caller's lines.
void WriteOverviews(const std::string& dir, const std::vector<AnalysisMapEntry>& entries,
                    const std::vector<MapJob>& jobs, const MapSetOptions& o) {
  for (const AnalysisMapEntry& e : entries) {
    const std::string base = (std::filesystem::path(dir) / e.prefix).string();
    std::vector<plot::MapImage> maps;
    for (const char* kind : {"axial_power", "tangential_power", "elevation"}) {
      for (const MapJob& job : jobs) {
        if (job.map->file != base + kind) continue;
        plot::MapImageOptions half = job.image;
        half.size_px = std::max(200, job.image.size_px / 2);
        maps.push_back(plot::RenderMap(job.map->grid, half));
      }
    }
    std::vector<std::string> lines =
        ClinicalSummaryLines(*e.analysis, e.kmax_location_determined, e.elevation_peak_location_determined);
    lines.insert(lines.end(), o.overview_lines.begin(), o.overview_lines.end());
    const std::string eye = o.eye.empty() ? "test surface (no eye)"
                                          : fmt::format("eye {} ({})", o.eye, o.eye == "OD" ? "right" : "left");
    plot::WriteMapPagePng(base + "overview.png", plot::ComposeMapPage(maps, "Overview: " + eye + e.label, lines));
  }
}

}  // namespace

void WriteAnalysisMapSet(const std::string& dir, const std::vector<AnalysisMapEntry>& entries,
                         const MapSetOptions& o) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw util::InputError(fmt::format("{}: cannot create directory: {}", dir, ec.message()));
  // The grids of each entry, then every file, on o.jobs threads: each item writes only its own slot or its own
  // files, and the scales are selected in between over the whole set, so the files do not depend on the threads.
  std::vector<EntryMaps> computed(entries.size());
  util::ParallelFor(entries.size(), o.jobs, [&](size_t k) { computed[k] = ComputeEntryMaps(dir, entries[k]); });
  std::vector<PendingMap> axial, tangential, elevation, difference, axial_uncertainty;
  for (EntryMaps& m : computed) {
    if (m.axial_uncertainty) axial_uncertainty.push_back(std::move(*m.axial_uncertainty));
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
    power_options.rings_are_sim_k_zone = true;
  }
  std::vector<MapJob> jobs;
  AddKind(axial, o.power, power_options, true, &jobs);
  AddKind(tangential, o.power, power_options, true, &jobs);
  AddKind(elevation, o.elevation, o, false, &jobs);
  AddKind(difference, o.elevation, o, false, &jobs);
  AddKind(axial_uncertainty, UncertaintyScale(), o, false, &jobs);
  util::ParallelFor(jobs.size(), o.jobs, [&](size_t k) {
    const MapJob& job = jobs[k];
    if (job.csv) plot::WriteMapCsv(job.map->file + ".csv", job.map->grid);
    plot::WriteMapPng(job.map->file + ".png", job.map->grid, job.image);
  });
  if (o.overview) WriteOverviews(dir, entries, jobs, o);
}

}  // namespace topocal::pipeline
