#pragma once
// The spots file (`ring,index,x_mm,y_mm`: detection-plane mm) that `simulate` and `undistort` write and
// `reconstruct --spots` and `undistort --spots` read: reader and writer side by side (header line, comma-separated,
// '#' comments allowed). The detector's richer file is correct/detected_spots_csv.h.
#include <string>
#include <vector>

#include "model/null_screen.h"

namespace topocal::model {

// Reads a spots file with header `ring,index,x_mm,y_mm`; throws util::InputError naming file and line.
std::vector<PlaneSpot> ReadSpotsCsv(const std::string& path);
std::string SpotsCsv(const std::vector<model::ImageSpot>& spots);

}  // namespace topocal::model
