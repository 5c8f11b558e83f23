#pragma once
// A difference over an image as a map (part of the plotting layer, plot/svg.h): each sample a point at its pixel,
// coloured by its band of difference (< 0.05, 0.05 - 0.1, 0.1 - 0.2, >= 0.2 px), drawn with the scatter plot
// (plot/scatter_plot.h) on linear axes, y up. The calibration's cross-validation map is drawn with it
// (calib::CrossValidationSvg).
#include <string>
#include <vector>

namespace topocal::plot {

struct DifferenceSample {
  double x_px = 0, y_px = 0;  // image pixel, y down
  double difference_px = 0;
};

struct DifferenceMap {
  std::string title;
  std::string note;         // one line under the map
  int image_height_px = 0;  // y is drawn as image_height_px - y
  std::vector<DifferenceSample> samples;
};

std::string RenderDifferenceMapSvg(const DifferenceMap& map);

}  // namespace topocal::plot
