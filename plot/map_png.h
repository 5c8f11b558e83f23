#pragma once
// Inside the plotting layer: the PNG bytes of a picture of maps drawn on stepped palettes (plot/map_png.cc) — a
// palette PNG whose palette is the bars' band colours, their hatched forms, the no-data grey, the marker and every
// 5th grey, or true colour when the bars are not stepped. Used by WriteMapPng and WriteMapPagePng.
#include <cstdint>
#include <string>
#include <vector>

#include "plot/map_image.h"

namespace topocal::plot {

// `bgr`: width x height pixels, 3 bytes each, row 0 at the top; `bars`: where its colour bars are drawn (a map's
// one, a page's several). `name` names the picture in errors. Throws std::runtime_error if encoding fails.
std::vector<unsigned char> MapPictureBytes(int width_px, int height_px, const std::vector<std::uint8_t>& bgr,
                                           const std::vector<PixelRect>& bars, const std::string& name);

}  // namespace topocal::plot
