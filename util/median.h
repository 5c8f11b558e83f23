#pragma once
// The median of a sample (the upper one of an even count; 0 for none): robust scales and centres across topocal.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace topocal::util {

inline double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto k = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), k, v.end());
  return *k;
}

}  // namespace topocal::util
