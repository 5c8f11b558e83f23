#pragma once
// The printable null screen as SVG (part of the plotting layer, plot/svg.h): the unrolled cone of model/null_screen_layout.h at 1:1 scale (document units
// are millimetres: width/height in mm and a viewBox in mm, so printing at 100 % gives true size).
//
// Drawn: the sector (filled black: the camera must see bright spots, docs/null-screen-print.md), every spot
// outline as a filled path (white; outlines cut by the seam are drawn on both edges and clipped to the sector so
// the halves join when the sheet is rolled), the cut lines (solid) and the fold line of the glue tab (dashed),
// azimuth ticks, the two rims named, a scale bar, a title and printing instructions.
#include <string>

#include "model/null_screen_layout.h"

namespace topocal::plot {

struct NullScreenSvgOptions {
  std::string title;            // e.g. the configuration's name; shown with the spot count
  bool bright_spots = true;     // true: white ellipses on a black sector (negative); false: black on white
  double glue_tab_mm = 8.0;     // width of the glue tab beyond the second seam edge
  double scale_bar_mm = 10.0;   // length of the scale bar
};

// The SVG document. Sheet y points up (model convention); SVG y points down, so y is flipped here.
std::string NullScreenSvg(const model::NullScreenLayout& layout, const NullScreenSvgOptions& options);

// The page NullScreenSvg draws on, width and height in mm (the SVG's width/height): the sheet to print.
Eigen::Vector2d NullScreenPageSizeMm(const model::NullScreenLayout& layout, const NullScreenSvgOptions& options);

}  // namespace topocal::plot
