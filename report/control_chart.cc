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

namespace {

// The Western Electric rules over the points' z-scores (in units of each point's sigma about the centre).
std::vector<ControlSignal> WesternElectricSignals(const std::vector<double>& z) {
  const int n = static_cast<int>(z.size());
  std::vector<ControlSignal> signals;
  // side +1 above the centre, -1 below, 0 on it.
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
    if (std::abs(z[i]) > 3) signals.push_back({i, 1});
    if (beyond(i, 3, 2, 2.0)) signals.push_back({i, 2});
    if (beyond(i, 5, 4, 1.0)) signals.push_back({i, 3});
    if (i >= 7 && side(i) != 0) {
      bool run = true;
      for (int k = i - 7; k <= i && run; ++k) run = side(k) == side(i);
      if (run) signals.push_back({i, 4});
    }
  }
  return signals;
}

}  // namespace

double ControlChart::PointSigma() const { return sigma / std::sqrt(static_cast<double>(subgroup_size)); }

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
  std::vector<double> z(n);
  for (int i = 0; i < n; ++i) z[i] = (values[i] - c.centre) / c.sigma;
  c.signals = WesternElectricSignals(z);
  for (const ControlSignal& s : c.signals) c.flagged[s.index] = true;
  return c;
}

void Subgroup::Add(double value, bool included) {
  ++n;
  mean += (value - mean) / n;
  if (!included) return;
  ++n_in;
  const double delta = value - mean_in;
  mean_in += delta / n_in;
  m2_in += delta * (value - mean_in);
}

void Subgroup::Merge(const Subgroup& next) {
  const int total = n + next.n;
  if (total == 0) return;
  mean = (n * mean + next.n * next.mean) / total;
  n = total;
  const int total_in = n_in + next.n_in;
  if (total_in > 0) {
    const double delta = next.mean_in - mean_in;
    m2_in += next.m2_in + delta * delta * n_in * next.n_in / total_in;
    mean_in += delta * next.n_in / total_in;
  }
  n_in = total_in;
}

std::optional<ControlChart> SubgroupMeansChart(const std::vector<Subgroup>& groups) {
  ControlChart c;
  double sum = 0, m2 = 0;
  int dof = 0, included_groups = 0;
  for (const Subgroup& g : groups) {
    if (!std::isfinite(g.mean) || !std::isfinite(g.mean_in) || !std::isfinite(g.m2_in)) return std::nullopt;
    c.subgroup_size = std::max(c.subgroup_size, g.n);
    if (g.n_in == 0) continue;
    ++included_groups;
    c.limit_points += g.n_in;
    sum += g.n_in * g.mean_in;
    m2 += g.m2_in;
    dof += g.n_in - 1;
  }
  if (included_groups < kMinControlChartPoints || dof == 0) return std::nullopt;
  c.centre = sum / c.limit_points;
  c.sigma = std::sqrt(m2 / dof);
  if (!std::isfinite(c.centre) || !std::isfinite(c.sigma)) return std::nullopt;
  const int n = static_cast<int>(groups.size());
  c.flagged.assign(n, false);
  if (!(c.sigma > 0)) return c;
  std::vector<double> z(n);
  for (int i = 0; i < n; ++i) z[i] = (groups[i].Point() - c.centre) / (c.sigma / std::sqrt(groups[i].n));
  c.signals = WesternElectricSignals(z);
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
