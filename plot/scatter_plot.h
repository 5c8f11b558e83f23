#pragma once
// A small, self-contained SVG scatter plot with logarithmic (or linear) axes, for the harness's plots and the
// calibration's cross-validation map (part of the plotting layer, plot/svg.h). Output is a
// pure function of the input (fixed number formatting), so equal data give byte-identical files.
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
};

// On a log axis, values <= 0 or below the axis' lower end (one decade under the smallest positive value, or the
// smallest line) are drawn on the axis itself, as hollow markers, so that no case disappears from the plot.
std::string RenderScatterSvg(const ScatterPlot& plot);

}  // namespace topocal::plot
