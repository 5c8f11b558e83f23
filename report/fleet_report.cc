#include "report/fleet_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "plot/svg.h"
#include "plot/svg_charts.h"
#include "util/version.h"

namespace topocal::report {

using plot::ControlChartPlot;
using plot::EscapeXml;
using plot::HistogramPlot;
using plot::SvgControlChart;
using plot::SvgHistogram;
namespace {

using nlohmann::json;

std::string H(std::string_view s) { return EscapeXml(s); }
std::string Sig(double v, int digits = 4) {
  if (!std::isfinite(v)) return "\u2014";
  if (v == 0) return "0";
  return fmt::format("{:.{}g}", v, digits);
}

// The parameters judged by a limit, in the order shown, then the calibration's own (no limit).
std::vector<FleetParameter> Parameters(const std::vector<FleetUnit>& units, const Limits& l) {
  std::vector<FleetParameter> p = {
      {"calibration_rms_px", "calibration RMS", "px", l.calibration_rms_px.max, false, true},
      {"sphere_radius_error_mm", "reference sphere radius error, corrected", "mm", l.sphere_radius_error_mm.max, true},
      {"sphere_power_error_D", "reference sphere power error, corrected", "D", l.sphere_power_error_D.max, true},
      {"seidel_sigma_per_mm2", "Seidel \u03c3", "mm\u207b\u00b2", std::nullopt, false},
  };
  std::set<std::string> calib, device;
  bool held_out = false;
  for (const FleetUnit& u : units) {
    for (const auto& [key, m] : u.measurements) {
      if (key.rfind("calib_", 0) == 0) calib.insert(key);
      if (key.rfind("device_", 0) == 0) device.insert(key);
      held_out = held_out || key == "held_out_radius_error_mm";
    }
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

// The judged size of a value: |value| (+ U under the guarded rule when the parameter has one).
std::optional<double> JudgedSize(const FleetParameter& p, const FleetMeasurement& m, DecisionRule rule) {
  if (!p.uses_U || rule == DecisionRule::kSimple) return std::abs(m.value);
  if (!m.U) return std::nullopt;  // guarded acceptance cannot decide without U
  return std::abs(m.value) + *m.U;
}

}  // namespace

FleetAnalysis AnalyseFleet(const std::string& database, std::vector<FleetUnit> units, const Limits& limits) {
  FleetAnalysis a;
  a.database = database;
  a.limits = limits;
  a.units = std::move(units);
  a.parameters = Parameters(a.units, limits);
  std::set<std::string> stations;
  for (const FleetUnit& u : a.units) stations.insert(u.station);
  a.stations.assign(stations.begin(), stations.end());

  for (const FleetUnit& u : a.units) {
    UnitVerdict v;
    v.pass = true;
    for (const FleetParameter& p : a.parameters) {
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
    a.verdicts.push_back(v);
  }

  for (const FleetParameter& p : a.parameters) {
    for (const std::string& station : [&] {
           std::vector<std::string> s{""};
           s.insert(s.end(), a.stations.begin(), a.stations.end());
           return s;
         }()) {
      if (!station.empty() && a.stations.size() < 2) continue;  // one station: its chart is the line's
      ChartSeries s;
      s.parameter = p.key;
      s.station = station;
      for (std::size_t i = 0; i < a.units.size(); ++i) {
        if (!station.empty() && a.units[i].station != station) continue;
        const auto it = a.units[i].measurements.find(p.key);
        if (it == a.units[i].measurements.end()) continue;
        s.units.push_back(i);
        s.values.push_back(it->second.value);
      }
      if (s.values.empty()) continue;
      // Phase I: the limits from the units that passed (a broken unit would widen them for every other one).
      std::vector<bool> passed;
      for (const std::size_t i : s.units) passed.push_back(a.verdicts[i].pass);
      s.chart = IndividualsChart(s.values, passed);
      if (s.chart && p.limit) {
        s.capability = CapabilityOf(*s.chart, p.one_sided ? std::nullopt : std::optional<double>(-*p.limit), *p.limit);
      }
      if (s.chart) {
        std::map<std::size_t, std::vector<int>> by_point;
        for (const ControlSignal& sig : s.chart->signals) by_point[static_cast<std::size_t>(sig.index)].push_back(sig.rule);
        for (const auto& [k, rules] : by_point) a.out_of_control.push_back({s.units[k], p.key, station, rules});
      }
      a.series.push_back(std::move(s));
    }
  }
  std::stable_sort(a.out_of_control.begin(), a.out_of_control.end(),
                   [](const OutOfControl& x, const OutOfControl& y) { return x.unit < y.unit; });
  return a;
}

namespace {

constexpr const char* kCss = R"css(
* { box-sizing: border-box; }
html { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
body { font-family: "DejaVu Sans", Arial, sans-serif; color: #1a1a1a; margin: 0; font-size: 10pt; line-height: 1.35; }
main { max-width: 190mm; margin: 0 auto; padding: 8mm 6mm; }
h1 { font-size: 16pt; margin: 0 0 2mm 0; }
h2 { font-size: 12.5pt; border-bottom: 1.5px solid #1a1a1a; padding-bottom: 1mm; margin: 6mm 0 3mm 0; }
h3 { font-size: 10.5pt; margin: 4mm 0 1mm 0; }
table.data { border-collapse: collapse; width: 100%; margin: 2mm 0; font-size: 9pt; }
table.data th, table.data td { border-bottom: 1px solid #c8c8c8; padding: 0.8mm 1.5mm; text-align: left; vertical-align: top; }
table.data th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.pass { color: #2e7d32; font-weight: bold; }
td.fail { color: #c62828; font-weight: bold; }
.note { color: #555; font-size: 8.5pt; }
svg.plot { width: 100%; height: auto; display: block; margin: 1mm 0; }
.pair { display: flex; gap: 3mm; break-inside: avoid; }
.pair > div { flex: 1 1 0; }
.parameter { break-inside: avoid; }
.stations { display: grid; grid-template-columns: 1fr 1fr; gap: 2mm; }
@page { size: A4; margin: 10mm 10mm 12mm 10mm;
  @bottom-right { content: "Page " counter(page) " of " counter(pages); font-family: "DejaVu Sans", Arial, sans-serif;
                  font-size: 8pt; color: #333; } }
@media print { main { max-width: none; padding: 0; } .page-break { break-before: page; } h2, h3 { break-after: avoid; } }
)css";

std::string UnitLabel(const FleetParameter& p) { return p.unit.empty() ? p.label : p.label + " (" + p.unit + ")"; }

// One series' control chart: its values, flagged points, centre and sigma (when there are enough units for a chart).
ControlChartPlot ChartPlotOf(const ChartSeries& series, std::string title, std::string value_label,
                             std::optional<double> limit) {
  ControlChartPlot c;
  c.title = std::move(title);
  c.value_label = std::move(value_label);
  c.values = series.values;
  if (series.chart) {
    c.flagged = series.chart->flagged;
    c.centre = series.chart->centre;
    c.sigma = series.chart->sigma;
  }
  c.limit = limit;
  return c;
}

std::string CapabilityText(const std::optional<Capability>& k) {
  if (!k) return "";
  return k->cp ? fmt::format(", Cp {}, Cpk {}", Sig(*k->cp, 3), Sig(k->cpk, 3)) : fmt::format(", Cpk {}", Sig(k->cpk, 3));
}

// Cpk (and Cp) of each judged parameter on the line's chart and each station's.
std::string CapabilityTable(const FleetAnalysis& a) {
  std::string rows;
  for (const FleetParameter& p : a.parameters) {
    if (!p.limit) continue;
    std::vector<std::string> charts{""};  // the line's, then each station's (when there are several)
    if (a.stations.size() > 1) charts.insert(charts.end(), a.stations.begin(), a.stations.end());
    std::string cells;
    for (const std::string& station : charts) {
      const auto it = std::find_if(a.series.begin(), a.series.end(), [&](const ChartSeries& cs) {
        return cs.parameter == p.key && cs.station == station;
      });
      const bool stated = it != a.series.end() && it->capability;
      cells += fmt::format("<td class=\"num\">{}</td>", stated ? CapabilityText(it->capability).substr(2) : "\u2014");
    }
    rows += fmt::format("<tr data-parameter=\"{}\"><td>{}</td>{}</tr>\n", H(p.key), H(p.label), cells);
  }
  if (rows.empty()) return "";
  std::string head = "<tr><th>capability</th><th>whole line</th>";
  if (a.stations.size() > 1) {
    for (const std::string& st : a.stations) head += "<th>" + H(st) + "</th>";
  }
  return "<table class=\"data\" id=\"capability\">" + head + "</tr>\n" + rows + "</table>\n";
}

std::string RulesText(const std::vector<int>& rules) {
  std::string s;
  for (int r : rules) s += (s.empty() ? "" : "; ") + fmt::format("rule {}: {}", r, WesternElectricRuleText(r));
  return s;
}

// The verdicts per station and for the whole line, then each judged parameter's capability.
std::string StationSummary(const FleetAnalysis& a) {
  std::string s;
  s += "<section id=\"summary\"><h2>Verdicts</h2>\n<table class=\"data\" id=\"stations\"><tr><th>station</th>"
       "<th>units</th><th>PASS</th><th>FAIL</th><th>yield</th><th>near a limit</th>"
       "<th>points out of control on its own charts</th></tr>\n";
  for (const std::string& st : [&] {
         std::vector<std::string> v = a.stations;
         if (a.stations.size() > 1) v.push_back("");
         return v;
       }()) {
    int n = 0, pass = 0, near = 0, ooc = 0;
    for (std::size_t i = 0; i < a.units.size(); ++i) {
      if (!st.empty() && a.units[i].station != st) continue;
      ++n;
      pass += a.verdicts[i].pass ? 1 : 0;
      near += (a.verdicts[i].pass && !a.verdicts[i].near.empty()) ? 1 : 0;
    }
    for (const OutOfControl& o : a.out_of_control) ooc += o.station == st ? 1 : 0;  // "" = the line's charts
    s += fmt::format("<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
                     "<td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td></tr>\n",
                     st.empty() ? "<strong>whole line</strong>" : H(st), n, pass, n - pass,
                     n > 0 ? fmt::format("{:.1f} %", 100.0 * pass / n) : std::string("\u2014"), near, ooc);
  }
  s += "</table>\n" + CapabilityTable(a) + "</section>\n";
  return s;
}

// Per parameter: distribution, the line's chart, each station's chart.
std::string ParameterSections(const FleetAnalysis& a) {
  std::string s;
  s += "<section id=\"parameters\" class=\"page-break\"><h2>Parameters</h2>\n";
  for (const FleetParameter& p : a.parameters) {
    std::vector<const ChartSeries*> series;
    for (const ChartSeries& cs : a.series) {
      if (cs.parameter == p.key) series.push_back(&cs);
    }
    if (series.empty()) continue;
    const ChartSeries& line = *series.front();
    s += fmt::format("<div class=\"parameter\" data-parameter=\"{}\"><h3>{}</h3>\n", H(p.key), H(UnitLabel(p)));
    double mean = 0, sd = 0;
    for (double v : line.values) mean += v;
    mean /= line.values.size();
    for (double v : line.values) sd += (v - mean) * (v - mean);
    sd = line.values.size() > 1 ? std::sqrt(sd / (line.values.size() - 1)) : 0;
    s += fmt::format("<p class=\"note\">n = {}, mean {}, standard deviation {}{}{}</p>\n", line.values.size(), Sig(mean),
                     Sig(sd),
                     line.chart ? fmt::format(", chart \u03c3 (moving range) {}, UCL {}, LCL {} (limits from {} passing "
                                              "units){}",
                                              Sig(line.chart->sigma), Sig(line.chart->Ucl()), Sig(line.chart->Lcl()),
                                              line.chart->limit_points, CapabilityText(line.capability))
                                : std::string(", too few passing units for a chart"),
                     p.limit ? fmt::format("; acceptance limit \u00b1{}", Sig(*p.limit)) : std::string());
    HistogramPlot hist{"Distribution", UnitLabel(p), line.values, p.limit};
    ControlChartPlot chart = ChartPlotOf(line, "Control chart, whole line", p.unit.empty() ? p.key : p.unit, p.limit);
    chart.x_labels = {a.units[line.units.front()].created_utc.substr(0, 10),
                      a.units[line.units.back()].created_utc.substr(0, 10)};
    s += "<div class=\"pair\"><div style=\"flex: 1 1 0\">" + SvgHistogram(hist) + "</div><div style=\"flex: 2 1 0\">" +
         SvgControlChart(chart) + "</div></div>\n";
    if (series.size() > 1) {
      s += "<div class=\"stations\">\n";
      for (std::size_t k = 1; k < series.size(); ++k) {
        const ChartSeries& st = *series[k];
        ControlChartPlot c = ChartPlotOf(st, "Station " + st.station, chart.value_label, p.limit);
        c.width = 420;
        c.height = 180;
        s += "<div>" + SvgControlChart(c) + "</div>\n";
      }
      s += "</div>\n";
    }
    s += "</div>\n";
  }
  s += "</section>\n";

  return s;
}

// Every unit, in time order, with its verdict (the table is closed by the caller with the page).
std::string UnitTable(const FleetAnalysis& a) {
  std::string s;
  s += "<section id=\"units\" class=\"page-break\"><h2>Units</h2>\n<table class=\"data\" id=\"unit-table\"><tr><th>#</th>"
       "<th>serial</th><th>calibrated</th><th>station</th><th>RMS (px)</th><th>sphere radius error (mm)</th>"
       "<th>sphere power error (D)</th><th>verdict</th></tr>\n";
  const auto value = [](const FleetUnit& u, const char* key) {
    const auto it = u.measurements.find(key);
    return it == u.measurements.end() ? std::string("\u2014") : Sig(it->second.value, 3);
  };
  for (std::size_t i = 0; i < a.units.size(); ++i) {
    const FleetUnit& u = a.units[i];
    s += fmt::format("<tr data-unit=\"{}\"><td class=\"num\">{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"num\">{}"
                     "</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"{}\">{}</td></tr>\n",
                     H(u.serial), i + 1, H(u.serial), H(u.created_utc), H(u.station), value(u, "calibration_rms_px"),
                     value(u, "sphere_radius_error_mm"), value(u, "sphere_power_error_D"),
                     a.verdicts[i].pass ? "pass" : "fail", a.verdicts[i].pass ? "PASS" : "FAIL");
  }
  return s;
}

}  // namespace

std::string RenderFleetHtml(const FleetAnalysis& a) {
  const int passed = static_cast<int>(std::count_if(a.verdicts.begin(), a.verdicts.end(),
                                                    [](const UnitVerdict& v) { return v.pass; }));
  std::string s = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  s += fmt::format("<title>topocal fleet report \u2014 {} units</title>\n<style>{}</style>\n</head>\n", a.units.size(),
                   kCss);
  s += fmt::format("<body data-units=\"{}\" data-passed=\"{}\" data-out-of-control=\"{}\">\n<main>\n", a.units.size(),
                   passed, a.out_of_control.size());
  s += "<h1>Fleet report: the production line</h1>\n";
  s += fmt::format("<p>Database {} \u00b7 {} units ({} records) from {} to {} \u00b7 {} station(s) \u00b7 topocal {}</p>\n",
                   H(a.database), [&] {
                     std::set<std::string> serials;
                     for (const FleetUnit& u : a.units) serials.insert(u.serial);
                     return serials.size();
                   }(),
                   a.units.size(), a.units.empty() ? "\u2014" : H(a.units.front().created_utc),
                   a.units.empty() ? "\u2014" : H(a.units.back().created_utc), a.stations.size(), H(kVersion));
  s += fmt::format("<p>Limits: {} ({} acceptance). {}</p>\n", H(a.limits.origin), ToString(a.limits.rule),
                   H(DecisionRuleText(a.limits.rule)));
  s += "<p class=\"note\">Control charts: Shewhart individuals charts, limits from the data of the units that "
       "passed (phase I: centre = mean, \u03c3 = mean moving range / 1.128, UCL/LCL = centre \u00b1 3\u03c3; a FAIL unit "
       "is charted and judged but does not set the limits), Western Electric rules 1\u20134; points flagged in red. "
       "Their in-control average run length is about 92 points: on a stable line of a few hundred units some signals "
       "are false alarms. Charts need at least 8 passing units. Capability: Cp = 2 limit / 6\u03c3, Cpk = (limit "
       "\u2212 |centre|) / 3\u03c3 of the values against \u00b1limit (one-sided for the RMS), \u03c3 the chart's; "
       "1.33 is the usual minimum of a capable process.</p>\n";

  s += StationSummary(a);
  // Units to look at.
  s += "<section id=\"attention\"><h2>Units out of control</h2>\n";
  if (a.out_of_control.empty()) {
    s += "<p id=\"no-signals\">No point on any chart breaks a Western Electric rule.</p>\n";
  } else {
    s += "<table class=\"data\" id=\"out-of-control\"><tr><th>unit</th><th>calibrated</th><th>station</th>"
         "<th>parameter</th><th>value</th><th>chart</th><th>rules</th></tr>\n";
    for (const OutOfControl& o : a.out_of_control) {
      const FleetUnit& u = a.units[o.unit];
      s += fmt::format("<tr data-serial=\"{}\" data-parameter=\"{}\"><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
                       "<td class=\"num\">{}</td><td>{}</td><td>{}</td></tr>\n",
                       H(u.serial), H(o.parameter), H(u.serial), H(u.created_utc), H(u.station), H(o.parameter),
                       Sig(u.measurements.at(o.parameter).value), o.station.empty() ? "line" : "station " + H(o.station),
                       H(RulesText(o.rules)));
    }
    s += "</table>\n";
  }
  s += "<h2>Units beyond or near their acceptance limits</h2>\n";
  std::string rows;
  for (std::size_t i = 0; i < a.units.size(); ++i) {
    const UnitVerdict& v = a.verdicts[i];
    if (v.pass && v.near.empty()) continue;
    std::string what;
    for (const auto& f : v.failed) what += (what.empty() ? "" : ", ") + f;
    for (const auto& f : v.near) what += (what.empty() ? "" : ", ") + f + " (near)";
    rows += fmt::format("<tr data-serial=\"{}\"><td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td><td>{}</td>"
                        "</tr>\n",
                        H(a.units[i].serial), H(a.units[i].serial), H(a.units[i].created_utc), H(a.units[i].station),
                        v.pass ? "pass" : "fail", v.pass ? "PASS" : "FAIL", H(what));
  }
  if (rows.empty()) {
    s += fmt::format("<p>Every unit passes with more than {:.0f} % of each limit to spare.</p>\n",
                     100 * (1 - kNearLimitFraction));
  } else {
    s += fmt::format("<p class=\"note\">Near: a passing unit whose judged value uses \u2265 {:.0f} % of its limit.</p>\n",
                     100 * kNearLimitFraction);
    s += "<table class=\"data\" id=\"near-limits\"><tr><th>unit</th><th>calibrated</th><th>station</th><th>verdict</th>"
         "<th>parameters</th></tr>\n" + rows + "</table>\n";
  }
  s += "</section>\n";

  s += ParameterSections(a);
  s += UnitTable(a);
  s += "</table></section>\n</main>\n</body>\n</html>\n";
  return s;
}

std::string FleetCsv(const FleetAnalysis& a) {
  // Station and serial are [A-Za-z0-9._-] for serials; a station name may hold anything: quoted (RFC 4180).
  const auto quote = [](const std::string& f) {
    if (f.find_first_of(",\"\n") == std::string::npos) return f;
    std::string q = "\"";
    for (char c : f) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  std::string csv = "serial,unit_json_sha256,created_utc,station,parameter,value,U,limit,unit_verdict\n";
  for (std::size_t i = 0; i < a.units.size(); ++i) {
    const FleetUnit& u = a.units[i];
    for (const FleetParameter& p : a.parameters) {
      const auto it = u.measurements.find(p.key);
      if (it == u.measurements.end()) continue;
      csv += fmt::format("{},{},{},{},{},{},{},{},{}\n", quote(u.serial), u.unit_json_sha256, quote(u.created_utc),
                         quote(u.station), p.key, it->second.value,
                         it->second.U ? fmt::format("{}", *it->second.U) : std::string(),
                         p.limit ? fmt::format("{}", *p.limit) : std::string(), a.verdicts[i].pass ? "PASS" : "FAIL");
    }
  }
  return csv;
}

json FleetJson(const FleetAnalysis& a) {
  json units = json::array();
  for (std::size_t i = 0; i < a.units.size(); ++i) {
    const FleetUnit& u = a.units[i];
    json m = json::object();
    for (const auto& [key, v] : u.measurements) {
      m[key] = {{"value", v.value}, {"U", v.U ? json(*v.U) : json(nullptr)}};
    }
    units.push_back({{"serial", u.serial},
                     {"unit_json_sha256", u.unit_json_sha256},
                     {"created_utc", u.created_utc},
                     {"station", u.station},
                     {"measurements", m},
                     {"verdict", a.verdicts[i].pass ? "PASS" : "FAIL"},
                     {"failed", a.verdicts[i].failed},
                     {"near_limit", a.verdicts[i].near}});
  }
  json charts = json::array();
  for (const ChartSeries& s : a.series) {
    json c = {{"parameter", s.parameter}, {"station", s.station.empty() ? json(nullptr) : json(s.station)},
              {"points", s.values.size()}};
    if (s.chart) {
      json signals = json::array();
      for (const ControlSignal& sig : s.chart->signals) {
        signals.push_back({{"serial", a.units[s.units[sig.index]].serial},
                           {"unit_json_sha256", a.units[s.units[sig.index]].unit_json_sha256},
                           {"rule", sig.rule}});
      }
      c["centre"] = s.chart->centre;
      c["sigma"] = s.chart->sigma;
      c["limit_points"] = s.chart->limit_points;
      if (s.capability) {
        c["cpk"] = s.capability->cpk;
        if (s.capability->cp) c["cp"] = *s.capability->cp;
      }
      c["ucl"] = s.chart->Ucl();
      c["lcl"] = s.chart->Lcl();
      c["signals"] = signals;
    }
    charts.push_back(c);
  }
  json ooc = json::array();
  for (const OutOfControl& o : a.out_of_control) {
    ooc.push_back({{"serial", a.units[o.unit].serial},
                   {"unit_json_sha256", a.units[o.unit].unit_json_sha256},
                   {"parameter", o.parameter},
                   {"chart", o.station.empty() ? std::string("line") : "station " + o.station},
                   {"rules", o.rules}});
  }
  json yield = json::array();
  for (const std::string& st : a.stations) {
    int n = 0, pass = 0;
    for (std::size_t i = 0; i < a.units.size(); ++i) {
      if (a.units[i].station != st) continue;
      ++n;
      pass += a.verdicts[i].pass ? 1 : 0;
    }
    yield.push_back({{"station", st}, {"units", n}, {"passed", pass}, {"yield", static_cast<double>(pass) / n}});
  }
  return {{"format", kFleetReportFormat},
          {"format_version", kFleetReportFormatVersion},
          {"tool_version", kVersion},
          {"database", a.database},
          {"schema_version", kFleetSchemaVersion},
          {"decision_rule", ToString(a.limits.rule)},
          {"limits_origin", a.limits.origin},
          {"near_limit_fraction", kNearLimitFraction},
          {"stations", a.stations},
          {"yield", yield},
          {"units", units},
          {"charts", charts},
          {"out_of_control", ooc}};
}

}  // namespace topocal::report
