#include "report/fleet_analysis.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

namespace topocal::report {
namespace {

// The judged size of a value: |value| (+ U under the guarded rule when the parameter has one).
std::optional<double> JudgedSize(const FleetParameter& p, const FleetMeasurement& m, DecisionRule rule) {
  if (!p.uses_U || rule == DecisionRule::kSimple) return std::abs(m.value);
  if (!m.U) return std::nullopt;  // guarded acceptance cannot decide without U
  return std::abs(m.value) + *m.U;
}

// The points of one series as they come: one per unit while there are at most kMaxChartPoints, then subgroups whose
// size doubles whenever the points would exceed it (pairs of neighbours merged: the groups stay consecutive units).
struct SeriesAccumulator {
  int m = 1;
  std::vector<ChartPoint> points;
  std::vector<bool> passed;      // m == 1: each point's unit passed (sets the limits)
  std::vector<Subgroup> groups;  // m > 1: each point's subgroup
  std::int64_t n = 0;
  double mean = 0, m2 = 0;  // Welford, every value

  // Whether the next unit's point would be a unit's own (so the unit must be kept to be named).
  bool NextIsUnitPoint() const { return m == 1 && static_cast<int>(points.size()) < kMaxChartPoints; }

  void Add(double value, bool pass, const FleetUnit& u, std::optional<std::size_t> kept) {
    ++n;
    const double delta = value - mean;
    mean += delta / static_cast<double>(n);
    m2 += delta * (value - mean);
    if (m == 1) {
      points.push_back({value, 1, u.serial, u.serial, u.created_utc, u.created_utc, u.unit_json_sha256, kept});
      passed.push_back(pass);
      if (static_cast<int>(points.size()) > kMaxChartPoints) ToPairs();
      return;
    }
    if (groups.back().n >= m) {
      groups.emplace_back();
      points.push_back({0, 0, u.serial, u.serial, u.created_utc, u.created_utc, u.unit_json_sha256, std::nullopt});
    }
    groups.back().Add(value, pass);
    ChartPoint& p = points.back();
    p.value = groups.back().Point();
    p.units = groups.back().n;
    p.last_serial = u.serial;
    p.last_utc = u.created_utc;
    if (static_cast<int>(groups.size()) > kMaxChartPoints) MergePairs();
  }

  // Individual points to subgroups of two.
  void ToPairs() {
    std::vector<ChartPoint> single = std::move(points);
    points.clear();
    groups.clear();
    for (std::size_t i = 0; i < single.size(); ++i) {
      if (i % 2 == 0) {
        groups.emplace_back();
        points.push_back(single[i]);
        points.back().unit.reset();
      }
      groups.back().Add(single[i].value, passed[i]);
      points.back().value = groups.back().Point();
      points.back().units = groups.back().n;
      points.back().last_serial = single[i].last_serial;
      points.back().last_utc = single[i].last_utc;
    }
    passed.clear();
    m = 2;
  }

  void MergePairs() {
    std::vector<Subgroup> g;
    std::vector<ChartPoint> p;
    for (std::size_t i = 0; i < groups.size(); i += 2) {
      g.push_back(groups[i]);
      p.push_back(points[i]);
      if (i + 1 < groups.size()) {
        g.back().Merge(groups[i + 1]);
        p.back().last_serial = points[i + 1].last_serial;
        p.back().last_utc = points[i + 1].last_utc;
      }
      p.back().value = g.back().Point();
      p.back().units = g.back().n;
    }
    groups = std::move(g);
    points = std::move(p);
    m *= 2;
  }
};

}  // namespace

std::vector<double> ChartSeries::Values() const {
  std::vector<double> v;
  for (const ChartPoint& p : points) v.push_back(p.value);
  return v;
}

std::vector<FleetParameter> FleetParameters(const std::vector<std::string>& keys, const Limits& l) {
  std::vector<FleetParameter> p = {
      {"calibration_rms_px", "calibration RMS", "px", l.calibration_rms_px.max, false, true},
      {"sphere_radius_error_mm", "reference sphere radius error, corrected", "mm", l.sphere_radius_error_mm.max, true},
      {"sphere_power_error_D", "reference sphere power error, corrected", "D", l.sphere_power_error_D.max, true},
      {"seidel_sigma_per_mm2", "Seidel \u03c3", "mm\u207b\u00b2", std::nullopt, false},
  };
  std::set<std::string> calib, device;
  bool held_out = false;
  for (const std::string& key : keys) {
    if (key.rfind("calib_", 0) == 0) calib.insert(key);
    if (key.rfind("device_", 0) == 0) device.insert(key);
    held_out = held_out || key == "held_out_radius_error_mm";
  }
  // The device stage's physical evidence first (a ball the fit did not use), then the fit's own numbers.
  if (held_out) p.push_back({"held_out_radius_error_mm", "held-out ball radius error, through the device", "mm",
                             std::nullopt, false});
  for (const std::string& key : device) {
    p.push_back({key, key == "device_chi2_per_dof" ? "device fit \u03c7\u00b2/dof" : "device parameter " + key.substr(7),
                 "", std::nullopt, false});
  }
  for (const std::string& key : calib) {
    p.push_back({key, "calibration parameter " + key.substr(6), "", std::nullopt, false});
  }
  return p;
}

UnitVerdict JudgeUnit(const FleetUnit& u, const std::vector<FleetParameter>& parameters, const Limits& limits) {
  UnitVerdict v;
  v.pass = true;
  for (const FleetParameter& p : parameters) {
    if (!p.limit) continue;
    const auto it = u.measurements.find(p.key);
    if (it == u.measurements.end()) {
      v.pass = false;
      v.failed.push_back(p.key + " (not measured)");
      continue;
    }
    const auto size = JudgedSize(p, it->second, limits.rule);
    if (!size || *size > *p.limit) {
      v.pass = false;
      v.failed.push_back(p.key);
    } else if (*size >= kNearLimitFraction * *p.limit) {
      v.near.push_back(p.key);
    }
  }
  return v;
}

struct FleetAnalyser::State {
  FleetAnalysis a;
  std::vector<FleetParameter> judged;  // the parameters with a limit
  std::map<std::string, StationCount> counts;
  std::set<std::string> keys;
  std::map<std::pair<std::string, std::string>, SeriesAccumulator> series;  // (parameter, station "" = line)
  std::size_t failed_kept = 0, near_kept = 0;
};

FleetAnalyser::FleetAnalyser(std::string database, const Limits& limits) : state_(std::make_unique<State>()) {
  state_->a.database = std::move(database);
  state_->a.limits = limits;
  state_->judged = FleetParameters({}, limits);
}

FleetAnalyser::~FleetAnalyser() = default;

void FleetAnalyser::Add(FleetUnit u) {
  State& s = *state_;
  FleetAnalysis& a = s.a;
  UnitVerdict v = JudgeUnit(u, s.judged, a.limits);
  const bool near = v.pass && !v.near.empty();
  for (const std::string& station : {std::string(), u.station}) {
    StationCount& c = s.counts[station];
    ++c.units;
    c.passed += v.pass ? 1 : 0;
    c.near += near ? 1 : 0;
  }
  if (a.unit_count == 0) a.first_utc = u.created_utc;
  a.last_utc = u.created_utc;
  ++a.unit_count;
  if (a.unit_count > static_cast<std::int64_t>(kMaxListedUnits)) a.units_complete = false;
  // Kept to be named: every unit of a small fleet, the FAIL and near ones up to the cap, and the units that are a
  // point of their own on some chart.
  bool keep = a.units_complete || (!v.pass && s.failed_kept < kMaxListedUnits) ||
              (near && s.near_kept < kMaxListedUnits);
  for (const auto& [key, m] : u.measurements) {
    s.keys.insert(key);
    for (const std::string& station : {std::string(), u.station}) keep = keep || s.series[{key, station}].NextIsUnitPoint();
  }
  std::optional<std::size_t> index;
  if (keep) {
    index = a.units.size();
    s.failed_kept += v.pass ? 0 : 1;
    s.near_kept += near ? 1 : 0;
  } else {
    a.failed_not_listed += v.pass ? 0 : 1;
    a.near_not_listed += near ? 1 : 0;
  }
  for (const auto& [key, m] : u.measurements) {
    for (const std::string& station : {std::string(), u.station}) {
      s.series[{key, station}].Add(m.value, v.pass, u, index);
    }
  }
  if (keep) {
    a.units.push_back(std::move(u));
    a.verdicts.push_back(std::move(v));
  }
}

namespace {

// A series' chart, capability, summary and the signals it adds to the out-of-control list.
ChartSeries FinishSeries(SeriesAccumulator&& acc, const FleetParameter& p, const std::string& station,
                         std::vector<OutOfControl>& out_of_control) {
  ChartSeries s;
  s.parameter = p.key;
  s.station = station;
  s.subgroup_size = acc.m;
  s.n = acc.n;
  s.mean = acc.mean;
  s.sd = acc.n > 1 ? std::sqrt(acc.m2 / static_cast<double>(acc.n - 1)) : 0;
  s.points = std::move(acc.points);
  if (acc.m == 1) {
    // Two passes over the values themselves, as a small series always had them.
    const std::vector<double> values = s.Values();
    double mean = 0, sd = 0;
    for (double v : values) mean += v;
    mean /= static_cast<double>(values.size());
    for (double v : values) sd += (v - mean) * (v - mean);
    s.mean = mean;
    s.sd = values.size() > 1 ? std::sqrt(sd / static_cast<double>(values.size() - 1)) : 0;
    // Phase I: the limits from the units that passed (a broken unit would widen them for every other one).
    s.chart = IndividualsChart(values, acc.passed);
  } else {
    s.chart = SubgroupMeansChart(acc.groups);
  }
  if (s.chart && p.limit) {
    s.capability = CapabilityOf(*s.chart, p.one_sided ? std::nullopt : std::optional<double>(-*p.limit), *p.limit);
  }
  if (s.chart) {
    std::map<std::size_t, std::vector<int>> by_point;
    for (const ControlSignal& sig : s.chart->signals) by_point[static_cast<std::size_t>(sig.index)].push_back(sig.rule);
    for (const auto& [k, rules] : by_point) out_of_control.push_back({s.points[k], p.key, station, rules});
  }
  return s;
}

}  // namespace

FleetAnalysis FleetAnalyser::Finish() {
  State& s = *state_;
  FleetAnalysis a = std::move(s.a);
  for (auto& [station, c] : s.counts) {
    c.station = station;
    if (!station.empty()) a.stations.push_back(station);
  }
  for (const std::string& st : a.stations) a.counts.push_back(s.counts.at(st));
  if (a.unit_count > 0) a.counts.push_back(s.counts.at(""));
  a.parameters = FleetParameters({s.keys.begin(), s.keys.end()}, a.limits);
  for (const FleetParameter& p : a.parameters) {
    std::vector<std::string> charts{""};  // the line's, then each station's (when there are several)
    if (a.stations.size() > 1) charts.insert(charts.end(), a.stations.begin(), a.stations.end());
    for (const std::string& station : charts) {
      const auto it = s.series.find({p.key, station});
      if (it == s.series.end() || it->second.n == 0) continue;
      a.series.push_back(FinishSeries(std::move(it->second), p, station, a.out_of_control));
    }
  }
  if (a.units_complete) {
    std::set<std::string> serials;
    for (const FleetUnit& u : a.units) serials.insert(u.serial);
    a.serial_count = static_cast<std::int64_t>(serials.size());
    for (ChartSeries& cs : a.series) {
      if (!cs.station.empty()) continue;
      std::vector<double> values;
      for (const FleetUnit& u : a.units) {
        if (const auto m = u.measurements.find(cs.parameter); m != u.measurements.end()) values.push_back(m->second.value);
      }
      cs.histogram = plot::BinValues(values);
    }
  }
  // In time order (a unit's point by its place in the fleet; a subgroup by its first unit's date).
  const auto key = [](const OutOfControl& o) {
    return std::pair(o.point.first_utc, o.point.unit.value_or(std::numeric_limits<std::size_t>::max()));
  };
  std::stable_sort(a.out_of_control.begin(), a.out_of_control.end(),
                   [&](const OutOfControl& x, const OutOfControl& y) { return key(x) < key(y); });
  return a;
}

FleetAnalysis AnalyseFleet(const std::string& database, std::vector<FleetUnit> units, const Limits& limits) {
  FleetAnalyser analyser(database, limits);
  for (FleetUnit& u : units) analyser.Add(std::move(u));
  return analyser.Finish();
}

}  // namespace topocal::report
