#pragma once
// Maps as files, part of the plotting layer (plot/svg.h): a scalar field over the cornea (power in
// D, height in µm) as a CSV grid and as a PNG a clinician or QA engineer can read: colour scale with a labelled colour
// bar, contour lines at round levels, axes in mm, title. Every PNG map topocal writes is drawn here; the grids are
// computed by topo/ (topo/map_grid.h, topo/power_map.h) and written by pipeline/map_output.h. Drawn with OpenCV
// (kept out of this header: topocal_plot links OpenCV privately, so callers get raw 8-bit BGR pixels, not a cv::Mat).
// See docs/maps.md for the conventions.
//
// Frame: model/grid_map.h's (row 0 of the grid, y_min, is drawn at the bottom of the plot). Equal scale on both axes.
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "model/grid_map.h"
#include "util/io.h"

namespace topocal::plot {

using model::GridMap;  // the maps plot/ draws are model/grid_map.h's

// Colour scales of OpenCV's applyColorMap. Turbo (default): Google's perceptually smoothed rainbow, low = blue,
// high = red, the clinical convention for power maps (steep = warm). Jet: the classic rainbow, for comparison.
enum class ColourScale { kTurbo, kJet };

// Printed at the bottom left of every map: how the picture is oriented (docs/maps.md).
inline constexpr const char* kDefaultMapOrientation = "camera view: x right, y up";

// A marked point: a filled disc in kMarkerBgr with a white ring and a black rim, about kMarkerRadiusPx (at the
// default size) so that it is seen on every colour of the scale (magenta is in neither Turbo nor Jet).
struct MapMarker {
  double x_mm = 0, y_mm = 0;
};
inline constexpr std::array<std::uint8_t, 3> kMarkerBgr = {255, 0, 255};
// A meridian drawn through the origin over [-half_length, half_length] along angle_deg (counter-clockwise from +x):
// black on a white underlay, solid or dashed.
struct MapAxis {
  double angle_deg = 0;
  double half_length_mm = 0;
  bool dashed = false;
};

struct MapImageOptions {
  int size_px = 800;                           // side of the (square) plot area; the image adds axes and colour bar
  std::optional<double> value_min, value_max;  // colour range; default: the data's range (rounded out to ticks)
  double contour_step = 0;                     // 0: a round step giving about 10 levels; < 0: no contour lines
  ColourScale scale = ColourScale::kTurbo;
  // One colour per contour band (the colour of the band's middle value), as clinical displays step their palettes:
  // a colour then names a band of values, read off the colour bar's bands. false: the continuous palette. Needs a
  // contour step (> 0, given or automatic); set by ApplyMapScale.
  bool stepped_palette = false;
  std::string scale_label;  // printed under the plot, e.g. "absolute scale, 1.5 D steps"
  // Lines printed under the title (a hook for clinical indices such as sim-K: the caller computes, the map prints).
  std::vector<std::string> annotations;
  // Circles about the origin, mm (a hook for the sim-K meridian ring), drawn dashed in black and white.
  std::vector<double> ring_radii_mm;
  // Clinical overlays, in the map's mm; the caller computes, the map draws (docs/maps.md):
  std::vector<MapMarker> markers;  // peaks: Kmax, the elevation peak
  std::vector<MapAxis> axes;       // meridians through the origin: the sim-K steep (solid) and flat (dashed)
  // The radius the data support in every direction: a dashed circle, and the map beyond it hatched (white stripes
  // over the colours) as extrapolated. 0: not drawn.
  double supported_radius_mm = 0;
  std::vector<std::string> legend;  // lines under the plot saying what the overlays are, with their numbers
  std::string eye;                  // "OD", "OS"; empty: not an eye (a test surface) or not given
  std::string orientation = kDefaultMapOrientation;
  bool IsValid(std::string* why) const;
};

// How the colour range of a set of maps is chosen (docs/maps.md, "Scales"). One scale is selected for every map of
// a set meant to be compared (a sweep, before/after, a unit's maps of one kind) and drawn on each of them.
enum class MapScaleKind {
  kAbsolute,    // fixed steps: the range [low, high] when given (widened by whole steps to hold the data only when
                // widen_to_data); else the data rounded out to whole steps, widened symmetrically to at least
                // kMinAbsoluteSteps steps
  kNormalised,  // the set's own range, at least min_span wide (centred on the data), rounded out to round ticks
};
struct MapScaleRequest {
  MapScaleKind kind = MapScaleKind::kNormalised;
  double step = 0;                  // absolute: the colour step (> 0)
  std::optional<double> low, high;  // absolute: the standard range, multiples of step apart
  bool widen_to_data = false;       // absolute with a range: widen it by whole steps to hold the set's data
  double min_span = 0;              // normalised: the smallest range drawn (so that a sphere looks flat)
  bool symmetric_about_zero = false;  // normalised: [-m, m], zero in the palette's middle (elevation, signed errors)
  bool IsValid(std::string* why) const;
};
// The standard absolute power scale: 1.5 D steps over 35.5-50.5 D, the range of normal corneas, after the
// Klyce-Wilson standardized scale (Wilson, Klyce & Husseini, Ophthalmology 1993;100:1723-7). Fixed: every power map
// on it shares one scale whatever its data, even when drawn one at a time (a sweep, a unit's record); values beyond
// it take the end colours and the map says how much of it lies beyond.
inline constexpr double kStandardPowerStepD = 1.5, kStandardPowerLowD = 35.5, kStandardPowerHighD = 50.5;
inline constexpr int kMinAbsoluteSteps = 10;
// Normalised scales: the smallest span drawn. 1 D: four of the 0.25 D steps a clinician acts on, so a map varying
// by less than 0.25 D uses at most a quarter of the palette. 1 um: elevation and height-error maps are read to a
// micrometre; a 20 nm residual of a corrected sphere must not fill the palette.
inline constexpr double kMinNormalisedSpanD = 1.0, kMinNormalisedSpanUm = 1.0;

// The extended absolute power scale for ectasia (keratoconus apices at 55-65 D, which the standard scale draws in
// its top colour): 2.5 D steps over 30-67.5 D, fixed like the standard one.
inline constexpr double kExtendedPowerStepD = 2.5, kExtendedPowerLowD = 30.0, kExtendedPowerHighD = 67.5;

MapScaleRequest StandardPowerScale();
MapScaleRequest ExtendedPowerScale();
// Absolute steps of `step` fitted to the set's data (at least kMinAbsoluteSteps steps): e.g. 0.5 D to see a
// cornea's detail on a scale whose colours still mean fixed powers within the set.
MapScaleRequest FittedStepScale(double step);
MapScaleRequest NormalisedScale(double min_span);
// The normalised scale symmetric about zero, as clinical elevation displays draw it: the range [-m, m] with m the
// set's largest |value| (at least min_span / 2) rounded out to a round tick, so that zero — on the reference
// surface — is the palette's middle colour and equal heights above and below it are equally far from it.
MapScaleRequest SymmetricScale(double min_span);

struct MapScale {
  double value_min = 0, value_max = 1, contour_step = 0;
  std::string label;  // e.g. "absolute scale, 1.5 D steps", "normalised scale (this set), minimum span 1 D"
};
// One scale for all `maps` (their finite values together; a set with no data gets [0, 1] widened as requested).
// Throws util::InputError for an invalid request or an empty set.
MapScale SelectMapScale(const std::vector<const GridMap*>& maps, const MapScaleRequest& request);
// The scale's range, contour step (the palette stepped at it) and label into the drawing options.
void ApplyMapScale(const MapScale& scale, MapImageOptions* options);

struct PixelRect {
  int x = 0, y = 0, width = 0, height = 0;  // top-left corner and size, pixels
};

// A rendered map: 8-bit BGR pixels and where things were drawn (for tests and for callers that compose figures).
struct MapImage {
  int width_px = 0, height_px = 0;
  std::vector<std::uint8_t> bgr;        // row-major, 3 bytes per pixel, row 0 at the top
  PixelRect plot;                       // the data area: x_min..x_max left to right, y_max..y_min top to bottom
  PixelRect colour_bar;                 // value_min at the bottom row, value_max at the top row
  double value_min = 0, value_max = 0;  // the colour range drawn
  double contour_step = 0;              // the contour step drawn (0: none)
  double px_per_mm = 0;                 // the plot's scale (equal on both axes)
  double x_min_mm = 0, y_max_mm = 0;    // the map point at the plot's top-left corner
  // The pixel (column, row) whose centre is nearest the map point (x, y) mm: where an overlay there was drawn.
  std::array<int, 2> PixelOf(double x_mm, double y_mm) const {
    return {plot.x + static_cast<int>(std::floor((x_mm - x_min_mm) * px_per_mm)),
            plot.y + static_cast<int>(std::floor((y_max_mm - y_mm) * px_per_mm))};
  }
  std::array<std::uint8_t, 3> Bgr(int x, int y) const {
    const size_t k = 3 * (static_cast<size_t>(y) * width_px + x);
    return {bgr[k], bgr[k + 1], bgr[k + 2]};
  }
};

// Colour of the scale at fraction t in [0, 1] of the range (clamped), BGR.
std::array<std::uint8_t, 3> ScaleColour(ColourScale scale, double t);
// The light grey drawn where the map has no data, BGR.
std::array<std::uint8_t, 3> NoDataColour();

// Renders the map. Throws util::InputError if the map or the options are invalid (see IsValid).
MapImage RenderMap(const GridMap& map, const MapImageOptions& options = {});
// Renders and writes a PNG atomically: a map on a stepped palette as a palette PNG (plot/map_png.cc: every band
// colour exact, anti-aliased edges of text and lines the nearest of the map's colours; about a fifth of the
// bytes of true colour), any other map in true colour. Throws util::InputError naming the path if it cannot be written.
void WriteMapPng(const std::string& path, const GridMap& map, const MapImageOptions& options = {});

// The map as CSV, long format: a header "x_mm,y_mm,<quantity>_<unit>" (e.g. value_D, value_um) then one row per
// grid point, row 0 (y_min) first, x ascending within a row; no data is an empty field. Numbers in the shortest
// form that reads back exactly.
std::string GridMapCsv(const GridMap& map);
// Writes GridMapCsv atomically. Throws util::InputError naming the path if it cannot be written.
void WriteMapCsv(const std::string& path, const GridMap& map);
// Reads a map CSV back (plot/map_csv.cc): the grid, its values (NaN where empty) and its unit (title empty).
// Throws util::InputError naming the path and line for anything GridMapCsv would not write.
GridMap ReadMapCsv(const std::string& path);

}  // namespace topocal::plot
