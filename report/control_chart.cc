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

std::optional<ControlChart> IndividualsChart(const std::vector<double>& values, const std::vector<bool>& in_limits) {
  const int n = static_cast<int>(values.size());
  for (double v : values) {
    if (!std::isfinite(v)) return std::nullopt;
  }
  ControlChart c;
  double sum = 0, mr = 0;
  std::optional<double> previous;
  for (int i = 0; i < n; ++i) {
    if (!in_limits.empty() && !in_limits[static_cast<size_t>(i)]) continue;
    sum += values[i];
    if (previous) mr += std::abs(values[i] - *previous);
    previous = values[i];
    ++c.limit_points;
  }
  if (c.limit_points < kMinControlChartPoints) return std::nullopt;
  c.centre = sum / c.limit_points;
  c.sigma = mr / (c.limit_points - 1) / kMovingRangeD2;
  // Values near the largest double (1e308 beside 0.1) overflow the sums: no limits can be drawn from them.
  if (!std::isfinite(c.centre) || !std::isfinite(c.sigma)) return std::nullopt;
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

std::optional<Capability> CapabilityOf(const ControlChart& chart, std::optional<double> lsl, double usl) {
  if (!(chart.sigma > 0)) return std::nullopt;
  Capability k;
  // (chart.centre and chart.sigma are finite: IndividualsChart gives no chart otherwise.)
  k.cpk = (usl - chart.centre) / (3 * chart.sigma);
  if (lsl) {
    k.cp = (usl - *lsl) / (6 * chart.sigma);
    k.cpk = std::min(k.cpk, (chart.centre - *lsl) / (3 * chart.sigma));
  }
  // A sigma of a few subnormals makes the ratios overflow: no capability is stated then.
  if (!std::isfinite(k.cpk) || (k.cp && !std::isfinite(*k.cp))) return std::nullopt;
  return k;
}

}  // namespace topocal::report
