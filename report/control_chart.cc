#include "report/control_chart.h"

#include <algorithm>
#include <cmath>

namespace topocal::report {

std::string WesternElectricRuleText(int rule) {
  switch (rule) {
    case 1: return "beyond 3\u03c3";
    case 2: return "2 of 3 beyond 2\u03c3, same side";
    case 3: return "4 of 5 beyond 1\u03c3, same side";
    case 4: return "8 in a row on one side of the centre";
    default: return "?";
  }
}

std::optional<ControlChart> IndividualsChart(const std::vector<double>& values) {
  const int n = static_cast<int>(values.size());
  if (n < kMinControlChartPoints) return std::nullopt;
  for (double v : values) {
    if (!std::isfinite(v)) return std::nullopt;
  }
  ControlChart c;
  double sum = 0, mr = 0;
  for (int i = 0; i < n; ++i) {
    sum += values[i];
    if (i > 0) mr += std::abs(values[i] - values[i - 1]);
  }
  c.centre = sum / n;
  c.sigma = mr / (n - 1) / kMovingRangeD2;
  c.flagged.assign(n, false);
  if (!(c.sigma > 0)) return c;
  // z-score of each point; side +1 above the centre, -1 below, 0 on it.
  std::vector<double> z(n);
  for (int i = 0; i < n; ++i) z[i] = (values[i] - c.centre) / c.sigma;
  const auto side = [&](int i) { return z[i] > 0 ? 1 : (z[i] < 0 ? -1 : 0); };
  // `need` of the last `window` points (ending at i) beyond `zone` sigma on the side of point i.
  const auto beyond = [&](int i, int window, int need, double zone) {
    if (i + 1 < window) return false;
    const int s = side(i);
    if (s == 0 || s * z[i] <= zone) return false;
    int count = 0;
    for (int k = i - window + 1; k <= i; ++k) count += (s * z[k] > zone) ? 1 : 0;
    return count >= need;
  };
  for (int i = 0; i < n; ++i) {
    if (std::abs(z[i]) > 3) c.signals.push_back({i, 1});
    if (beyond(i, 3, 2, 2.0)) c.signals.push_back({i, 2});
    if (beyond(i, 5, 4, 1.0)) c.signals.push_back({i, 3});
    if (i >= 7 && side(i) != 0) {
      bool run = true;
      for (int k = i - 7; k <= i && run; ++k) run = side(k) == side(i);
      if (run) c.signals.push_back({i, 4});
    }
  }
  for (const ControlSignal& s : c.signals) c.flagged[s.index] = true;
  return c;
}

}  // namespace topocal::report
