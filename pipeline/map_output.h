#pragma once
// Writes the maps of analyses into a directory: CSV grids and PNG images (plot/map_image.h), every map of one kind
// in a set on one shared colour scale.
#include <optional>
#include <string>
#include <vector>

#include "model/config.h"
#include "plot/map_image.h"
#include "topo/analysis.h"
#include "topo/sphere_fit.h"

namespace topocal::pipeline {

// One analysis of a set (a sweep's sigma, a stage of a before/after pair).
struct AnalysisMapEntry {
  std::string prefix;                        // file name prefix, e.g. "sphere_corrected_"
  std::string label;                         // appended to each title, e.g. " - reference sphere, corrected"
  const topo::Analysis* analysis = nullptr;
  const model::BiconicParams* truth = nullptr;  // the known surface: adds the height-difference map
  // Printed under the power maps' titles; empty: the analysis's clinical summary (sim-K with axes, cylinder, Kmax).
  std::vector<std::string> power_annotations;
  // U (k = 2) of the axial power at each sample of the analysis's polar map (MeasurementUncertainty::
  // axial_expanded_D): adds <prefix>axial_uncertainty.{csv,png}, beside the axial map it qualifies.
  const std::vector<double>* axial_expanded_D = nullptr;
  // false: the data do not determine the peak's location (QuantityUncertainty::determined): no dot, and the legend
  // says so.
  bool kmax_location_determined = true, elevation_peak_location_determined = true;
};

struct MapSetOptions {
  bool csv = true;                                  // the CSV grid beside each PNG (~0.6 MB each)
  int size_px = plot::MapImageOptions{}.size_px;    // side of the PNGs' plot area
  plot::MapScaleRequest power = plot::StandardPowerScale();                             // axial and tangential
  plot::MapScaleRequest elevation = plot::SymmetricScale(plot::kMinNormalisedSpanUm);  // elevation, height error
  std::string eye;                                  // "OD", "OS" or empty (test surface)
  std::vector<double> power_ring_radii_mm;          // rings on the power maps; empty: the sim-K zone (0.5, 1.5 mm)
  bool rings_are_sim_k_zone = false;                // set when the rings are the default (the legend says so)
  // Threads computing and writing the maps (0: every core); the files are the same whatever the number.
  int jobs = 1;
  // Also <prefix>overview.png per entry: its axial, tangential and elevation maps as drawn (at half size) on one
  // page with the clinical numbers (ClinicalSummaryLines) and these lines after them — e.g. the capture-quality
  // line — the clinical topographers' overview display.
  bool overview = false;
  std::vector<std::string> overview_lines;
};

// The clinical numbers of an analysis in words, as the maps print them: sim-K (with its axes when the cylinder shows
// at 0.01 D), Kmax and the elevation peak with where they lie (or that the location is not determined), the best-fit
// sphere; or why there are none.
std::vector<std::string> ClinicalSummaryLines(const topo::Analysis& analysis, bool kmax_location_determined = true,
                                              bool elevation_peak_location_determined = true);

// Files per entry: <prefix>axial_power.{csv,png}, <prefix>tangential_power.{csv,png}, <prefix>elevation.{csv,png}
// (elevation above the best-fit sphere, um, its radius in the title) and, with `truth`,
// <prefix>height_difference.{csv,png} (Eq. 26, ideal - recovered, um); with `axial_expanded_D`,
// <prefix>axial_uncertainty.{csv,png} on a fixed scale (0-0.5 D in 0.05 D steps, widened by whole steps to hold the data). Each kind of map is drawn on one scale
// selected over the whole set (plot::SelectMapScale). Creates `dir` if needed. Throws util::InputError naming the
// path when a file cannot be written.
void WriteAnalysisMapSet(const std::string& dir, const std::vector<AnalysisMapEntry>& entries,
                         const MapSetOptions& options = {});

// The data of an analysis's maps, as the CSVs hold them: axial and tangential power (D) resampled from the polar
// power maps, and the elevation (µm) above the best-fit sphere of the clinical indices (or, without them, of the
// recovered sag over the covered disc) — absent when no sphere fits. 241 x 241 samples over the map's disc; NaN
// outside it.
struct AnalysisGrids {
  model::GridMap axial_D, tangential_D;
  std::optional<model::GridMap> elevation_um;
  topo::SphereFit best_fit_sphere;
};
AnalysisGrids AnalysisGridsOf(const topo::Analysis& analysis);

}  // namespace topocal::pipeline
