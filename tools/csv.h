#pragma once
// Small CSV helpers for the command line's point files (header line, comma-separated, '#' comments allowed).
#include <string>
#include <vector>

#include "model/null_screen.h"

namespace topocal::tools {

struct SpotRow {
  model::SpotId id;
  double x_mm = 0, y_mm = 0;
};

// Reads a spots file with header `ring,index,x_mm,y_mm`; throws model::InputError naming file and line.
std::vector<SpotRow> ReadSpotsCsv(const std::string& path);
std::string SpotsCsv(const std::vector<model::ImageSpot>& spots);

}  // namespace topocal::tools
