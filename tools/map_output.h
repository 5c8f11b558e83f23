#pragma once
// Writes the maps of one analysis into a directory: CSV grids and PNG images (topo/map_image.h).
#include <string>

#include "model/config.h"
#include "topo/analysis.h"
#include "topo/map_image.h"

namespace topocal::tools {

// Files: <prefix>axial_power.{csv,png}, <prefix>tangential_power.{csv,png}, <prefix>height.{csv,png} and, when
// `truth` is given, <prefix>height_difference.{csv,png} (Eq. 26, ideal - recovered, um); the CSV grids only when
// `csv` (each is ~0.6 MB); `size_px` is the side of the PNGs' plot area. Creates `dir` if needed.
// Throws model::InputError naming the path when a file cannot be written.
void WriteAnalysisMaps(const std::string& dir, const std::string& prefix, const std::string& label,
                       const topo::Analysis& analysis, const model::BiconicParams* truth, bool csv = true,
                       int size_px = topo::MapImageOptions{}.size_px);

}  // namespace topocal::tools
