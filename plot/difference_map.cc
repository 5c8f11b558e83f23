#include "plot/difference_map.h"

#include <limits>

#include "plot/scatter_plot.h"

namespace topocal::plot {

std::string RenderDifferenceMapSvg(const DifferenceMap& map) {
  ScatterPlot plot;
  plot.title = map.title;
  plot.x_label = "x (px)";
  plot.y_label = "image height - y (px)";
  plot.log_x = plot.log_y = false;
  struct Band {
    double upper_px;
    const char* label;
    const char* colour;
  };
  const Band bands[] = {{0.05, "< 0.05 px", "#2ca02c"},
                        {0.1, "0.05 - 0.1 px", "#bcbd22"},
                        {0.2, "0.1 - 0.2 px", "#ff7f0e"},
                        {std::numeric_limits<double>::infinity(), ">= 0.2 px", "#d62728"}};
  for (const Band& band : bands) plot.series.push_back({band.label, band.colour, {}});
  for (const DifferenceSample& s : map.samples) {
    size_t b = 0;
    while (s.difference_px >= bands[b].upper_px) ++b;
    plot.series[b].points.push_back({s.x_px, map.image_height_px - s.y_px});
  }
  plot.note = map.note;
  return RenderScatterSvg(plot);
}

}  // namespace topocal::plot
