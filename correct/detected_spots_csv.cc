#include "correct/detected_spots_csv.h"

#include <algorithm>

#include <fmt/format.h>

namespace topocal::correct {

std::string DetectedSpotsCsv(const DetectAndIndexResult& result) {
  std::vector<LocatedSpot> identified = result.spots;
  identified.insert(identified.end(), result.excluded.begin(), result.excluded.end());
  std::sort(identified.begin(), identified.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  std::string out = "ring,index,x_mm,y_mm,u_px,v_px,flags\n";
  const auto row = [&out](const LocatedSpot& s) {
    out += fmt::format("{},{},{:.10f},{:.10f},{:.6f},{:.6f},{}\n", s.id.ring, s.id.index, s.position_mm.x(),
                       s.position_mm.y(), s.position_px.x(), s.position_px.y(), SpotFlagsText(s.flags));
  };
  for (const auto& s : identified) row(s);
  for (const auto& s : result.unassigned) row(s);
  return out;
}

}  // namespace topocal::correct
