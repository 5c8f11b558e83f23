#include "model/grid_map.h"

#include <cmath>

namespace topocal::model {

bool GridMap::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (nx < 2 || ny < 2) return fail("the grid needs at least 2 x 2 samples");
  if (!(x_max_mm > x_min_mm) || !(y_max_mm > y_min_mm) || !std::isfinite(x_min_mm + x_max_mm + y_min_mm + y_max_mm)) {
    return fail("the grid's extent must be finite with x_max > x_min and y_max > y_min");
  }
  if (values.size() != static_cast<std::size_t>(nx) * ny) return fail("values must hold nx * ny samples");
  for (double v : values) {
    if (std::isinf(v)) return fail("values must be finite or NaN (no data)");
  }
  return true;
}

}  // namespace topocal::model
