#pragma once
// Sample statistics shared across topocal: the median (robust scales and centres) and the sample standard deviation.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace topocal::util {

inline double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto k = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), k, v.end());
  return *k;
}

// Sample standard deviation, n - 1 in the denominator (GUM's experimental standard deviation); 0 for fewer than 2.
inline double SampleStddev(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  double mean = 0;
  for (const double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  double sum2 = 0;
  for (const double x : v) sum2 += (x - mean) * (x - mean);
  return std::sqrt(sum2 / static_cast<double>(v.size() - 1));
}

}  // namespace topocal::util
