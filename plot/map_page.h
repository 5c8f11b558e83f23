#pragma once
// One page of maps with the numbers read with them: the clinical topographers' overview ("4 maps") display — the
// maps in a grid of two columns, a title line above them, and text lines (sim-K, Kmax, elevation, the capture's
// quality) in the grid's next cell. Part of the plotting layer (plot/map_image.h draws the maps).
#include <string>
#include <vector>

#include "plot/map_image.h"
#include "util/io.h"

namespace topocal::plot {

struct MapPage {
  int width_px = 0, height_px = 0;
  std::vector<std::uint8_t> bgr;  // row-major, 3 bytes per pixel, row 0 at the top
  std::vector<PixelRect> panels;  // where each map was placed, in the order given
  PixelRect text;                 // the cell holding the text lines
  std::vector<std::string> text_lines;  // the lines drawn there, after wrapping to the cell's width
  std::vector<PixelRect> colour_bars;   // the maps' colour bars, where they now lie on the page
};

// The maps (1 to 8) in two columns, each pixel for pixel as rendered, cells as large as the largest map; `title`
// above them; `lines` in the cell after the last map, wrapped at spaces to its width, in the maps' label size.
// Throws util::InputError for no map, more than 8, or a map without pixels.
MapPage ComposeMapPage(const std::vector<MapImage>& maps, const std::string& title,
                       const std::vector<std::string>& lines);
// ComposeMapPage written as a PNG atomically: a palette PNG when the maps are on stepped palettes, as WriteMapPng
// writes them (every band colour exact), else true colour. Throws util::InputError naming the path if it cannot be
// written.
void WriteMapPagePng(const std::string& path, const MapPage& page);

}  // namespace topocal::plot
