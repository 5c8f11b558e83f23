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

}  // namespace

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
  c.values = series.Values();
  c.subgroup_size = series.subgroup_size;
  if (series.chart) {
    c.flagged = series.chart->flagged;
    c.centre = series.chart->centre;
    c.sigma = series.chart->PointSigma();
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
  for (const StationCount& c : a.counts) {
    if (c.station.empty() && a.stations.size() < 2) continue;  // one station: its row is the line's
    int ooc = 0;
    for (const OutOfControl& o : a.out_of_control) ooc += o.station == c.station ? 1 : 0;  // "" = the line's charts
    s += fmt::format("<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
                     "<td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td></tr>\n",
                     c.station.empty() ? "<strong>whole line</strong>" : H(c.station), c.units, c.passed,
                     c.units - c.passed,
                     c.units > 0 ? fmt::format("{:.1f} %", 100.0 * static_cast<double>(c.passed) / c.units)
                                 : std::string("\u2014"),
                     c.near, ooc);
  }
  s += "</table>\n" + CapabilityTable(a) + "</section>\n";
  return s;
}

// The line chart's limits: of the units (individuals chart) or of the subgroup means.
std::string ChartNote(const ChartSeries& line) {
  if (!line.chart) return ", too few passing units for a chart";
  const ControlChart& c = *line.chart;
  if (line.subgroup_size == 1) {
    return fmt::format(", chart \u03c3 (moving range) {}, UCL {}, LCL {} (limits from {} passing units){}", Sig(c.sigma),
                       Sig(c.Ucl()), Sig(c.Lcl()), c.limit_points, CapabilityText(line.capability));
  }
  return fmt::format(", chart of the means of {} consecutive units ({} points): \u03c3 within subgroups {}, UCL {}, "
                     "LCL {} of a mean (limits from {} passing units){}",
                     line.subgroup_size, line.points.size(), Sig(c.sigma), Sig(c.Ucl()), Sig(c.Lcl()), c.limit_points,
                     CapabilityText(line.capability));
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
    s += fmt::format("<p class=\"note\">n = {}, mean {}, standard deviation {}{}{}</p>\n", line.n, Sig(line.mean),
                     Sig(line.sd), ChartNote(line),
                     p.limit ? fmt::format("; acceptance limit \u00b1{}", Sig(*p.limit)) : std::string());
    HistogramPlot hist{"Distribution", UnitLabel(p), {}, line.histogram, p.limit};
    if (!hist.bins) hist.values = line.Values();
    ControlChartPlot chart = ChartPlotOf(line, "Control chart, whole line", p.unit.empty() ? p.key : p.unit, p.limit);
    chart.x_labels = {line.points.front().first_utc.substr(0, 10), line.points.back().last_utc.substr(0, 10)};
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
  if (!a.units_complete) {
    return fmt::format("<section id=\"units\" class=\"page-break\"><h2>Units</h2>\n<p id=\"units-not-listed\">{} "
                       "records: more than the {} this page lists; the CSV (<code>--csv</code>) has every one.</p>\n"
                       "<table>",
                       a.unit_count, kMaxListedUnits);
  }
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

// One point that breaks a rule: a unit, or a subgroup by its first and last unit.
std::string OutOfControlRow(const FleetAnalysis& a, const OutOfControl& o) {
  const ChartPoint& pt = o.point;
  std::string who, when, station;
  if (pt.unit) {
    const FleetUnit& u = a.units[*pt.unit];
    who = H(u.serial);
    when = H(u.created_utc);
    station = H(u.station);
  } else {
    who = fmt::format("{} \u2026 {} ({} units)", H(pt.first_serial), H(pt.last_serial), pt.units);
    when = H(pt.first_utc) + " \u2026 " + H(pt.last_utc);
    station = o.station.empty() ? "all" : H(o.station);
  }
  return fmt::format("<tr data-serial=\"{}\" data-parameter=\"{}\"><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
                     "<td class=\"num\">{}</td><td>{}</td><td>{}</td></tr>\n",
                     H(pt.first_serial), H(o.parameter), who, when, station, H(o.parameter),
                     pt.unit ? Sig(pt.value) : "mean " + Sig(pt.value),
                     o.station.empty() ? "line" : "station " + H(o.station), H(RulesText(o.rules)));
}

}  // namespace

std::string RenderFleetHtml(const FleetAnalysis& a) {
  const std::int64_t passed = a.counts.empty() ? 0 : a.counts.back().passed;
  std::string s = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  s += fmt::format("<title>topocal fleet report \u2014 {} units</title>\n<style>{}</style>\n</head>\n", a.unit_count,
                   kCss);
  s += fmt::format("<body data-units=\"{}\" data-passed=\"{}\" data-out-of-control=\"{}\">\n<main>\n", a.unit_count,
                   passed, a.out_of_control.size());
  s += "<h1>Fleet report: the production line</h1>\n";
  s += fmt::format("<p>Database {} \u00b7 {} units ({} records) from {} to {} \u00b7 {} station(s) \u00b7 topocal {}</p>\n",
                   H(a.database), a.serial_count, a.unit_count, a.unit_count == 0 ? "\u2014" : H(a.first_utc),
                   a.unit_count == 0 ? "\u2014" : H(a.last_utc), a.stations.size(), H(kVersion));
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
    for (const OutOfControl& o : a.out_of_control) s += OutOfControlRow(a, o);
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
  if (a.failed_not_listed + a.near_not_listed > 0) {
    rows += fmt::format("<tr id=\"not-listed\"><td colspan=\"5\">and {} FAIL and {} near units more: the CSV "
                        "(<code>--csv</code>) has every unit with its verdict</td></tr>\n",
                        a.failed_not_listed, a.near_not_listed);
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

std::string FleetCsvHeader() {
  return "serial,unit_json_sha256,created_utc,station,parameter,value,U,limit,unit_verdict\n";
}

std::string FleetCsvRows(const std::vector<FleetParameter>& parameters, const FleetUnit& u, const UnitVerdict& verdict) {
  // Station and serial are [A-Za-z0-9._-] for serials; a station name may hold anything: quoted (RFC 4180).
  const auto quote = [](const std::string& f) {
    if (f.find_first_of(",\"\n") == std::string::npos) return f;
    std::string q = "\"";
    for (char c : f) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  std::string csv;
  for (const FleetParameter& p : parameters) {
    const auto it = u.measurements.find(p.key);
    if (it == u.measurements.end()) continue;
    csv += fmt::format("{},{},{},{},{},{},{},{},{}\n", quote(u.serial), u.unit_json_sha256, quote(u.created_utc),
                       quote(u.station), p.key, it->second.value,
                       it->second.U ? fmt::format("{}", *it->second.U) : std::string(),
                       p.limit ? fmt::format("{}", *p.limit) : std::string(), verdict.pass ? "PASS" : "FAIL");
  }
  return csv;
}

std::string FleetCsv(const FleetAnalysis& a) {
  std::string csv = FleetCsvHeader();
  for (std::size_t i = 0; i < a.units.size(); ++i) csv += FleetCsvRows(a.parameters, a.units[i], a.verdicts[i]);
  return csv;
}

namespace {

// A chart's point: its unit, or its subgroup by first and last serial.
json PointJson(const ChartPoint& p) {
  if (p.unit) return {{"serial", p.first_serial}, {"unit_json_sha256", p.first_sha256}};
  return {{"first_serial", p.first_serial}, {"last_serial", p.last_serial}, {"units", p.units}};
}

}  // namespace

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
              {"points", s.points.size()}, {"units", s.n}, {"subgroup_size", s.subgroup_size}};
    if (s.chart) {
      json signals = json::array();
      for (const ControlSignal& sig : s.chart->signals) {
        json j = PointJson(s.points[static_cast<std::size_t>(sig.index)]);
        j["rule"] = sig.rule;
        signals.push_back(j);
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
    json j = PointJson(o.point);
    j["parameter"] = o.parameter;
    j["chart"] = o.station.empty() ? std::string("line") : "station " + o.station;
    j["rules"] = o.rules;
    ooc.push_back(j);
  }
  json yield = json::array();
  for (const StationCount& c : a.counts) {
    if (c.station.empty()) continue;
    yield.push_back({{"station", c.station}, {"units", c.units}, {"passed", c.passed},
                     {"yield", static_cast<double>(c.passed) / static_cast<double>(c.units)}});
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
          {"unit_count", a.unit_count},
          {"units_complete", a.units_complete},
          {"units", units},
          {"charts", charts},
          {"out_of_control", ooc}};
}

}  // namespace topocal::report
