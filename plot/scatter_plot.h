#pragma once
// A small, self-contained SVG scatter plot with logarithmic (or linear) axes, for the harness's plots and the
// calibration's cross-validation map (part of the plotting layer, plot/svg.h). Output is a
// pure function of the input (fixed number formatting), so equal data give byte-identical files.
#include <cstddef>
#include <string>
#include <vector>

namespace topocal::plot {

struct PlotPoint {
  double x = 0, y = 0;
};

struct PlotSeries {
  std::string label;
  std::string colour;  // any SVG colour, e.g. "#1f77b4"
  std::vector<PlotPoint> points;
};

struct PlotLine {
  double value = 0;
  std::string label;
  std::string colour;
};

struct ScatterPlot {
  std::string title;
  std::string x_label;
  std::string y_label;
  bool log_x = true;
  bool log_y = true;
  std::vector<PlotSeries> series;
  std::vector<PlotLine> horizontal;  // e.g. a limit
  std::vector<PlotLine> vertical;    // e.g. the answer
  std::string note;                  // one line under the plot
  // Markers drawn at most (0: every point). Beyond it each series keeps, per cell of a square grid over the plot, the
  // first of its points in the cell (in the order given) at that point's place, the cell growing from 3 px (the
  // marker's radius) by factors of 2 until the markers fit: the file's size is bounded whatever the number of
  // points, the same points give the same file, and the legend says how many points each series has and how the
  // markers were thinned.
  size_t max_markers = 0;
};

// On a log axis, values <= 0 or below the axis' lower end (one decade under the smallest positive value, or the
// smallest line) are drawn on the axis itself, as hollow markers, so that no case disappears from the plot.
std::string RenderScatterSvg(const ScatterPlot& plot);

}  // namespace topocal::plot
