#include "correct/detected_spots_csv.h"

#include <algorithm>

#include <fmt/format.h>

namespace topocal::correct {

std::vector<LocatedSpot> DetectedSpotRows(const DetectAndIndexResult& result) {
  std::vector<LocatedSpot> rows = result.spots;
  rows.insert(rows.end(), result.excluded.begin(), result.excluded.end());
  std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  rows.insert(rows.end(), result.unassigned.begin(), result.unassigned.end());
  return rows;
}

std::string DetectedSpotsCsv(const DetectAndIndexResult& result) {
  std::string out = "ring,index,x_mm,y_mm,u_px,v_px,flags\n";
  for (const LocatedSpot& s : DetectedSpotRows(result)) {
    out += fmt::format("{},{},{:.10f},{:.10f},{:.6f},{:.6f},{}\n", s.id.ring, s.id.index, s.position_mm.x(),
                       s.position_mm.y(), s.position_px.x(), s.position_px.y(), SpotFlagsText(s.flags));
  }
  return out;
}

}  // namespace topocal::correct
