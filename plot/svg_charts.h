#pragma once
// Inline SVG plots for the QA and fleet reports (part of the plotting layer, plot/svg.h): no scripts, no external fonts or images, deterministic text (every number
// printed by fmt with a fixed precision), so the same record gives the same bytes.
//
// Image-space plots use OpenCV's pixel convention (x right, y down, the centre of the top-left pixel at (0, 0)),
// scaled to a fixed drawing width; vectors are magnified by a 1-2-5 factor chosen so the longest is visible, and a
// scale bar says how long a given displacement is drawn.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>
#include "util/io.h"

namespace topocal::plot {

// The largest 1, 2 or 5 x 10^n not above x (x > 0); 1 for x <= 0 or not finite.
double NiceFloor(double x);

struct Bar {
  std::string label;
  double value = 0;
};

struct BarChartOptions {
  std::string title;
  std::string value_label;      // axis label with unit, e.g. "RMS (px)"
  std::optional<double> limit;  // drawn as a dashed line
  std::string limit_label;
};

// Vertical bars, one per entry, with the value printed above each bar. Values must be finite and >= 0.
std::string SvgBarChart(const std::vector<Bar>& bars, const BarChartOptions& options);

struct Arrow {
  double x_px = 0, y_px = 0;    // base, image pixels
  double dx_px = 0, dy_px = 0;  // the vector, pixels
  bool highlight = false;       // drawn in the warning colour (outliers)
};

// A scalar field over the image on a regular cols x rows grid of cells (row-major, row 0 at the top), drawn as
// coloured cells under the arrows with a colour bar.
struct CellField {
  int cols = 0, rows = 0;
  std::vector<double> values;  // NaN: no data (drawn light grey)
  std::string label;  // colour-bar label with unit
  // The colour bar's range; default: the finite values' range. A value beyond it takes the end colour.
  std::optional<double> value_min, value_max;
};

// A part of the image, pixels (x right, y down).
struct PixelRegion {
  double x_px = 0, y_px = 0, width_px = 0, height_px = 0;
};

struct QuiverOptions {
  int image_width_px = 0, image_height_px = 0;
  std::optional<PixelRegion> region;        // draw only this part of the image (default: all of it)
  std::string title;
  std::string caption_unit = "px";          // unit of the vectors in the scale bar
  std::optional<double> magnification;      // default: chosen from the longest vector
  std::optional<CellField> background;
};

// Arrows over the image frame, magnified, with a scale bar. Throws util::InputError for a non-positive image
// size or a non-finite vector.
std::string SvgQuiver(const std::vector<Arrow>& arrows, const QuiverOptions& options);

// A series in time order with its control limits (report/control_chart.h): points joined by a line, the centre and
// the 1, 2, 3 sigma lines, flagged points in the warning colour, and the acceptance limits +-limit as dashed lines
// when they lie within twice the plotted range (else the caption says they are off scale).
struct ControlChartPlot {
  std::string title;
  std::string value_label;          // axis label with unit
  std::vector<double> values;
  std::vector<bool> flagged;        // same size as values (or empty)
  std::optional<double> centre, sigma;
  std::optional<double> limit;      // acceptance: |value| <= limit
  std::vector<std::string> x_labels;  // first and last tick labels (dates), may be empty
  int subgroup_size = 1;            // units per point: > 1 for a chart of subgroup means
  double width = 640, height = 220;
};
std::string SvgControlChart(const ControlChartPlot& plot);

// Equal bins over [lo, hi] (the smallest and largest value) of n finite values: ceil(sqrt(n)) bins, at least 5 and at
// most kMaxHistogramBins (more than the plot has pixels for says nothing more). Value x falls in bin
// min(bins - 1, int((x - lo) / ((hi - lo) / bins))); all values equal: the middle bin. A database bins its values
// with the same expression in SQL (report/fleet_db.h FleetDb::Histogram) and gets the same counts.
inline constexpr int kMaxHistogramBins = 60;
int HistogramBinCount(std::size_t n);
struct HistogramBins {
  double lo = 0, hi = 0;
  std::vector<std::int64_t> counts;
  std::int64_t n = 0;
};
HistogramBins BinValues(const std::vector<double>& values);  // the finite ones

// Histogram (HistogramBins: of `values`, or `bins` when given, e.g. counted by a database), acceptance limits
// +-limit dashed when in range.
struct HistogramPlot {
  std::string title, value_label;
  std::vector<double> values;
  std::optional<HistogramBins> bins;
  std::optional<double> limit;
  double width = 320, height = 200;
};
std::string SvgHistogram(const HistogramPlot& plot);

}  // namespace topocal::plot
