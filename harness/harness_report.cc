#include "harness/harness_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>

#include "plot/scatter_plot.h"
#include "util/json_section.h"
#include "util/version.h"

namespace topocal::harness {
namespace {

using nlohmann::json;

const char* kFamilyColours[] = {"#1f77b4", "#d62728", "#2ca02c"};

// Markers a plot draws at most (plot::ScatterPlot::max_markers): ~45 bytes each, so a plot stays under ~250 KB for
// any number of cases; the bundled configurations (<= 1,647 cases) draw every case.
constexpr size_t kMaxPlotMarkers = 5000;

const char* MapsName(const HarnessRun& run) { return run.config.limits.tangential_map ? "axial+tangential" : "axial"; }

// One row per case, formatted straight into the output (no string per number: at a million cases the temporaries
// were a third of a merge's time); numbers with 9 significant digits ({:.9g}).
std::string CasesCsv(const HarnessRun& run) {
  std::string out =
      "case,cornea,family,coefficient,calibration_error,azimuth_deg,noise_px,draw,seed,status,residual_max_um,"
      "residual_rms_um,"
      "residual_max_px,residual_rms_px,spots_used,undistort_failures,dk_x,dk_y,dr_x_mm,dr_y_mm,dP_axial_max_D,"
      "dP_tangential_max_D,dpv_axial_D,dpv_tangential_D,compared_radius_mm,within_limits\n";
  out.reserve(out.size() + run.cases.size() * 280);  // ~255 bytes a row
  auto to = std::back_inserter(out);
  const double pitch = run.config.pixel_pitch_um;
  for (const auto& c : run.cases) {
    const auto& s = c.spec;
    const bool assembly = s.kind == HarnessCaseKind::kAssembly;
    fmt::format_to(to, "{},{},{},{:.9g},", s.index, run.config.corneas[s.cornea].name,
                   assembly ? AssemblyAxisName(s.axis) : DistortionFamilyName(s.family),
                   assembly ? s.error : s.coefficient);
    if (!assembly) fmt::format_to(to, "{:.9g}", s.calibration_error);
    out += ',';
    if (assembly && IsDirectional(s.axis)) fmt::format_to(to, "{:.9g}", s.azimuth_deg);
    fmt::format_to(to, ",{:.9g},{},{},{},{:.9g},{:.9g},{:.9g},{:.9g},{},{},", s.noise_px, s.draw, s.seed,
                   c.ok ? "ok" : "failed", c.residual_max_um, c.residual_rms_um, c.residual_max_um / pitch,
                   c.residual_rms_um / pitch, c.spots_used, c.undistort_failures);
    if (c.ok) {
      fmt::format_to(to, "{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{}\n", c.dk_x, c.dk_y,
                     c.dr_x_mm, c.dr_y_mm, c.dP_axial_max_D, c.dP_tangential_max_D, c.dpv_axial_D,
                     c.dpv_tangential_D, c.compared_radius_mm, LimitUtilisation(c, run.config.limits) <= 1 ? 1 : 0);
    } else {
      out += ",,,,,,,,,0\n";  // no number for a case that has none (never NaN)
    }
  }
  return out;
}

json AnswerJson(const HarnessRun& run, const InverseAnswer& a) {
  json j = {{"found", a.found},
            {"noise_alone_exceeds", a.noise_alone_exceeds},
            {"residual_max_um", a.residual_max_um},
            {"residual_max_px", a.residual_max_px},
            {"sigma_equivalent_per_mm2", a.sigma_equivalent_per_mm2},
            {"grid_all_pass_up_to_um", a.grid_all_pass_up_to_um},
            {"grid_first_failure_um", a.grid_first_failure_um},
            {"max_tested_um", a.max_tested_um},
            {"limited_by", a.limited_by},
            {"limiting_case", a.limiting_case}};
  json families = json::object();
  for (const auto& f : a.families) {
    families[DistortionFamilyName(f.family)] = {{"found", f.found},
                                                {"residual_max_um", f.residual_max_um},
                                                {"residual_max_px", f.residual_max_um / run.config.pixel_pitch_um}};
  }
  j["per_family"] = families;
  return j;
}

json CaseJson(const HarnessRun& run, int index) {
  const auto& c = run.cases[static_cast<size_t>(index)];
  json j = {{"case", c.spec.index}, {"cornea", run.config.corneas[c.spec.cornea].name}};
  if (c.spec.kind == HarnessCaseKind::kAssembly) {
    j["axis"] = AssemblyAxisName(c.spec.axis);
    j["error"] = c.spec.error;
    if (IsDirectional(c.spec.axis)) j["azimuth_deg"] = c.spec.azimuth_deg;
  } else {
    j["family"] = DistortionFamilyName(c.spec.family);
    j["coefficient"] = c.spec.coefficient;
    j["calibration_error"] = c.spec.calibration_error;
  }
  j["noise_px"] = c.spec.noise_px;
  j["residual_max_um"] = c.residual_max_um;
  j["dk"] = c.MaxAbsDk();
  j["dP_D"] = c.MaxAbsDP_D(run.config.limits);
  return j;
}

json AssemblyAnswerJson(const HarnessRun& run, const InverseAnswer& a) {
  json axes = json::object();
  for (const auto& x : a.assembly) {
    json j = {{"unit", AssemblyAxisUnit(x.axis)},
              {"found", x.found},
              {"noise_alone_exceeds", x.noise_alone_exceeds},
              {"max_error", x.max_error},
              {"grid_all_pass_up_to", x.grid_all_pass_up_to},
              {"grid_first_failure", x.grid_first_failure},
              {"max_tested", x.max_tested},
              {"limited_by", x.limited_by}};
    if (x.axis == AssemblyAxis::kPrincipalPoint) j["max_error_px"] = x.max_error / (run.config.pixel_pitch_um * 1e-3);
    if (x.axis == AssemblyAxis::kARelative) j["max_error_mm"] = x.max_error * run.config.design.topographer.a_mm;
    j["limiting_case"] = x.limiting_case >= 0 ? CaseJson(run, x.limiting_case) : json(nullptr);
    axes[AssemblyAxisName(x.axis)] = j;
  }
  return axes;
}

std::string SummaryJson(const HarnessRun& run, const InverseAnswer& a) {
  json j;
  j["format"] = "topocal-harness-summary";
  j["topocal_version"] = kVersion;
  j["config_sha256"] = run.config_sha256;
  j["config"] = json::parse(CanonicalHarnessJson(run.config));
  j["cases"] = {{"total", run.total_cases},
                {"within_limits", a.cases_within},
                {"outside_limits", a.cases_outside},
                {"failed", a.cases_failed}};
  j["limits"] = {{"dk", run.config.limits.dk}, {"dP_D", run.config.limits.dP_D}, {"dP_maps", MapsName(run)}};
  if (run.config.HasDistortion()) j["answer"] = AnswerJson(run, a);
  if (run.config.HasAssembly()) j["assembly_answer"] = AssemblyAnswerJson(run, a);
  j["truth"] = HarnessTruthJson(run.truth);
  if (a.limiting_case >= 0) j["limiting_case"] = CaseJson(run, a.limiting_case);
  return util::JsonFileText(j);
}

std::string AnswerSentence(const HarnessRun& run, const InverseAnswer& a) {
  const auto& l = run.config.limits;
  if (!a.found) {
    return fmt::format(
        "every case is within |dk| <= {:g} and |dP| <= {:g} D ({}) up to the largest residual tested, "
        "{:.4g} um ({:.4g} px, |sigma| {:.3g} mm^-2 equivalent): the answer is at least that",
        l.dk, l.dP_D, MapsName(run), a.residual_max_um, a.residual_max_px, a.sigma_equivalent_per_mm2);
  }
  if (a.noise_alone_exceeds && a.residual_max_um == 0) {
    return fmt::format("none: the spot-position noise alone puts a case outside |dk| <= {:g} or |dP| <= {:g} D ({})",
                       l.dk, l.dP_D, MapsName(run));
  }
  return fmt::format(
      "largest residual distortion keeping every case within |dk| <= {:g} and |dP| <= {:g} D ({}): "
      "{:.4g} um at the detection plane = {:.4g} px = |sigma| {:.3g} mm^-2 equivalent",
      l.dk, l.dP_D, MapsName(run), a.residual_max_um, a.residual_max_px, a.sigma_equivalent_per_mm2);
}

std::string ErrorText(AssemblyAxis axis, double value) {
  const std::string unit = AssemblyAxisUnit(axis);
  return unit.empty() ? fmt::format("{:.4g}", value) : fmt::format("{:.4g} {}", value, unit);
}

std::string CaseDescription(const HarnessRun& run, int index) {
  const auto& c = run.cases[static_cast<size_t>(index)];
  if (c.spec.kind == HarnessCaseKind::kAssembly) {
    return fmt::format("case {}: cornea {}, {} = {}{}, noise {:g} px draw {}: |dk| {:.4g}, |dP| {:.4g} D{}",
                       c.spec.index, run.config.corneas[c.spec.cornea].name, AssemblyAxisName(c.spec.axis),
                       ErrorText(c.spec.axis, c.spec.error),
                       IsDirectional(c.spec.axis) ? fmt::format(" at azimuth {:g} deg", c.spec.azimuth_deg) : "",
                       c.spec.noise_px, c.spec.draw, c.MaxAbsDk(), c.MaxAbsDP_D(run.config.limits),
                       c.ok ? "" : " (reconstruction failed: " + c.failure + ")");
  }
  return fmt::format(
      "case {}: cornea {}, {} = {:.4g}, calibration error {:+g}, noise {:g} px draw {}: residual "
      "{:.4g} um, |dk| {:.4g}, |dP| {:.4g} D{}",
      c.spec.index, run.config.corneas[c.spec.cornea].name, DistortionFamilyName(c.spec.family), c.spec.coefficient,
      c.spec.calibration_error, c.spec.noise_px, c.spec.draw, c.residual_max_um, c.MaxAbsDk(),
      c.MaxAbsDP_D(run.config.limits), c.ok ? "" : " (reconstruction failed: " + c.failure + ")");
}

std::string AssemblyAnswerLine(const HarnessRun& run, const AssemblyAnswer& x) {
  std::string value;
  if (x.noise_alone_exceeds && x.max_error == 0) {
    value = "none (the noise alone is outside the limits)";
  } else {
    value = (x.found ? "" : ">= ") + ErrorText(x.axis, x.max_error);
    if (x.axis == AssemblyAxis::kPrincipalPoint) {
      value += fmt::format(" = {:.4g} px", x.max_error / (run.config.pixel_pitch_um * 1e-3));
    }
    if (x.axis == AssemblyAxis::kARelative) {
      value += fmt::format(" ({:.3g} %, {:.4g} mm of a)", 100 * x.max_error,
                           x.max_error * run.config.design.topographer.a_mm);
    }
  }
  return value;
}

std::string AssemblySentence(const HarnessRun& run) {
  const auto& l = run.config.limits;
  return fmt::format(
      "largest assembly error, one axis at a time, measured through the nominal device (uncorrected), "
      "keeping every cornea, direction, noise level and draw within |dk| <= {:g} and |dP| <= {:g} D ({})",
      l.dk, l.dP_D, MapsName(run));
}

// Text for a markdown table cell: a | would end the cell.
std::string Cell(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

std::string AssemblyAnswerMd(const HarnessRun& run, const InverseAnswer& a) {
  std::string md = "## Assembly errors of the device (uncorrected)\n\n**Inverse answer:** " + AssemblySentence(run) +
                   ":\n\n| axis | largest error within the limits | limited by | grid: all pass up to | smallest "
                   "failing | limiting case |\n|---|---:|---|---:|---:|---|\n";
  for (const auto& x : a.assembly) {
    md += fmt::format("| {} | {} | {} | {:.4g} | {} | {} |\n", AssemblyAxisName(x.axis), AssemblyAnswerLine(run, x),
                      x.found ? x.limited_by : "-", x.grid_all_pass_up_to,
                      x.found ? fmt::format("{:.4g}", x.grid_first_failure) : "-",
                      x.limiting_case >= 0 ? Cell(CaseDescription(run, x.limiting_case)) : "none outside the limits");
  }
  return md + "\n";
}

std::string AssemblyRowsMd(const HarnessRun& run) {
  std::string md =
      "\n## Cases by assembly error\n\nWorst over corneas, directions, noise levels and draws; the "
      "residual is the displacement of the noise-free spots from the nominal device's, on the detection "
      "plane.\n\n| axis | error | residual max (um) | max \\|dk\\| | max \\|dP\\| (D) | dpv axial (D) | "
      "within limits |\n|---|---:|---:|---:|---:|---:|---:|\n";
  struct Row {
    double residual = 0, dk = 0, dP = 0, dpv_lo = 0, dpv_hi = 0;
    int within = 0, total = 0, failed = 0;
  };
  std::map<std::pair<int, double>, Row> rows;
  for (const auto& c : run.cases) {
    if (c.spec.kind != HarnessCaseKind::kAssembly) continue;
    Row& r = rows[{static_cast<int>(c.spec.axis), c.spec.error}];
    r.residual = std::max(r.residual, c.residual_max_um);
    r.dk = std::max(r.dk, c.MaxAbsDk());
    r.dP = std::max(r.dP, c.MaxAbsDP_D(run.config.limits));
    if (c.ok) {
      r.dpv_lo = std::min(r.dpv_lo, c.dpv_axial_D);
      r.dpv_hi = std::max(r.dpv_hi, c.dpv_axial_D);
    }
    r.within += LimitUtilisation(c, run.config.limits) <= 1 ? 1 : 0;
    r.failed += c.ok ? 0 : 1;
    ++r.total;
  }
  for (const AssemblyAxis axis : kAssemblyAxes) {
    for (const double v : run.config.Errors(axis)) {
      const auto it = rows.find({static_cast<int>(axis), v});
      if (it == rows.end()) continue;  // a value listed twice is one row
      const Row& r = it->second;
      md += fmt::format("| {} | {} | {:.4g} | {:.3g} | {:.3g} | {:+.3g} ... {:+.3g} | {}/{}{} |\n",
                        AssemblyAxisName(axis), ErrorText(axis, v), r.residual, r.dk, r.dP, r.dpv_lo, r.dpv_hi,
                        r.within, r.total, r.failed ? fmt::format(" ({} failed)", r.failed) : "");
      rows.erase(it);
    }
  }
  return md;
}

std::string TableMd(const HarnessRun& run, const InverseAnswer& a) {
  const auto& cfg = run.config;
  std::string md = cfg.HasDistortion() ? (cfg.HasAssembly() ? "# Residual-distortion and assembly-error harness\n\n"
                                                            : "# Residual-distortion harness\n\n")
                                       : "# Assembly-error harness\n\n";
  md += fmt::format("Configuration SHA-256 `{}`; {} cases; limits |dk| <= {:g}, |dP| <= {:g} D ({} maps).\n\n",
                    run.config_sha256, run.total_cases, cfg.limits.dk, cfg.limits.dP_D, MapsName(run));
  if (cfg.HasDistortion()) md += "**Inverse answer:** " + AnswerSentence(run, a) + ".\n\n";
  if (cfg.HasDistortion() && a.found) {
    md += fmt::format(
        "Grid bounds: every tested case with a residual up to {:.4g} um is within the limits; the "
        "smallest residual of a case outside them is {:.4g} um. Limiting {} ({}).\n\n",
        a.grid_all_pass_up_to_um, a.grid_first_failure_um, CaseDescription(run, a.limiting_case), a.limited_by);
  }
  if (cfg.HasAssembly()) md += AssemblyAnswerMd(run, a);
  if (cfg.HasDistortion()) md += "| family | largest tolerable residual (um) | (px) |\n|---|---:|---:|\n";
  for (const auto& f : a.families) {
    md += fmt::format("| {} | {}{:.4g} | {:.4g} |\n", DistortionFamilyName(f.family),
                      f.found ? "" : ">= ", f.residual_max_um, f.residual_max_um / cfg.pixel_pitch_um);
  }
  md += "\n## Truth reconstructions (undistorted, noise-free spots)\n\n";
  md +=
      "| cornea | r_x (mm) | r_y (mm) | k_x | k_y | alpha (deg) | covered radius (mm) | spots |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& t : run.truth) {
    md += fmt::format("| {} | {:.5f} | {:.5f} | {:.5f} | {:.5f} | {:.4f} | {:.3f} | {} |\n", t.cornea, t.fit.rx_mm,
                      t.fit.ry_mm, t.fit.kx, t.fit.ky, t.fit.alpha_deg, t.covered_radius_mm, t.spots);
  }
  if (cfg.HasAssembly()) md += AssemblyRowsMd(run);
  if (!cfg.HasDistortion()) return md;
  md +=
      "\n## Cases by distortion and calibration error\n\nWorst over corneas, noise levels and draws. "
      "e = -1 is no correction.\n\n";
  md +=
      "| family | coefficient | e | residual max (um) | (px) | max \\|dk\\| | max \\|dP\\| (D) | within limits |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|\n";
  struct Row {
    double residual = 0, dk = 0, dP = 0;
    int within = 0, total = 0, failed = 0;
  };
  std::map<std::tuple<int, double, double>, Row> rows;
  for (const auto& c : run.cases) {
    if (c.spec.kind != HarnessCaseKind::kDistortion) continue;
    Row& r = rows[{static_cast<int>(c.spec.family), c.spec.coefficient, c.spec.calibration_error}];
    r.residual = std::max(r.residual, c.residual_max_um);
    r.dk = std::max(r.dk, c.MaxAbsDk());
    r.dP = std::max(r.dP, c.MaxAbsDP_D(run.config.limits));
    r.within += LimitUtilisation(c, cfg.limits) <= 1 ? 1 : 0;
    r.failed += c.ok ? 0 : 1;
    ++r.total;
  }
  for (const DistortionFamily f : kDistortionFamilies) {
    for (const double coefficient : cfg.Coefficients(f)) {
      for (const double e : cfg.calibration_errors) {
        const auto it = rows.find({static_cast<int>(f), coefficient, e});
        if (it == rows.end()) continue;  // a value listed twice is one row
        const Row& r = it->second;
        md += fmt::format("| {} | {:.4g} | {:+g} | {:.4g} | {:.4g} | {:.3g} | {:.3g} | {}/{}{} |\n",
                          DistortionFamilyName(f), coefficient, e, r.residual, r.residual / cfg.pixel_pitch_um, r.dk,
                          r.dP, r.within, r.total, r.failed ? fmt::format(" ({} failed)", r.failed) : "");
        rows.erase(it);
      }
    }
  }
  return md;
}

std::string Plot(const HarnessRun& run, const InverseAnswer& a, bool power) {
  plot::ScatterPlot p;
  p.max_markers = kMaxPlotMarkers;
  p.title = power ? "Power-map error against residual distortion" : "Conic-constant error against residual distortion";
  p.x_label = "residual distortion, max displacement over the spot field (um, detection plane)";
  p.y_label = power ? fmt::format("max |P - P_truth| over the disc, {} map{} (D)", MapsName(run),
                                  run.config.limits.tangential_map ? "s" : "")
                    : "max |k - k_truth| of k_x, k_y";
  int failed = 0;
  for (const DistortionFamily f : kDistortionFamilies) {
    if (run.config.Coefficients(f).empty()) continue;
    plot::PlotSeries s;
    s.label = DistortionFamilyName(f);
    s.colour = kFamilyColours[static_cast<int>(f)];
    for (const auto& c : run.cases) {
      if (c.spec.kind != HarnessCaseKind::kDistortion || c.spec.family != f) continue;
      if (!c.ok) {
        ++failed;
        continue;
      }
      // No residual is drawn on the axis (hollow), not at a meaningless 1e-10 um.
      s.points.push_back({c.residual_max_um <= kZeroResidualUm ? 0.0 : c.residual_max_um,
                          power ? c.MaxAbsDP_D(run.config.limits) : c.MaxAbsDk()});
    }
    p.series.push_back(std::move(s));
  }
  p.horizontal.push_back(
      {power ? run.config.limits.dP_D : run.config.limits.dk,
       power ? fmt::format("limit {:g} D", run.config.limits.dP_D) : fmt::format("limit {:g}", run.config.limits.dk),
       "#000000"});
  if (a.found && a.residual_max_um > 0) {
    p.vertical.push_back({a.residual_max_um, fmt::format("answer {:.3g} um", a.residual_max_um), "#7f3fbf"});
  }
  p.note = fmt::format("{} cases; hollow markers: below the axis (no residual, or error below the axis){}",
                       run.total_cases, failed ? fmt::format("; {} failed reconstructions not drawn", failed) : "");
  return plot::RenderScatterSvg(p);
}

// |dk| and |dP| of one assembly axis as fractions of their limits against |error|: which one limits, and where.
std::string AssemblyPlot(const HarnessRun& run, const AssemblyAnswer& x) {
  const auto& l = run.config.limits;
  const std::string unit = AssemblyAxisUnit(x.axis);
  plot::ScatterPlot p;
  p.max_markers = kMaxPlotMarkers;
  p.title = fmt::format("{}: errors measured through the nominal device", AssemblyAxisName(x.axis));
  p.x_label = unit.empty() ? fmt::format("|{}| (relative)", AssemblyAxisName(x.axis))
                           : fmt::format("|{}| ({})", AssemblyAxisName(x.axis), unit);
  p.y_label = "error / its limit";
  plot::PlotSeries dk{fmt::format("|dk| / {:g}", l.dk), kFamilyColours[0], {}};
  plot::PlotSeries dP{fmt::format("|dP| / {:g} D ({})", l.dP_D, MapsName(run)), kFamilyColours[1], {}};
  int failed = 0, cases = 0;
  for (const auto& c : run.cases) {
    if (c.spec.kind != HarnessCaseKind::kAssembly || c.spec.axis != x.axis) continue;
    ++cases;
    if (!c.ok) {
      ++failed;
      continue;
    }
    const double e = std::abs(c.spec.error);  // 0 is drawn on the axis (hollow)
    dk.points.push_back({e, c.MaxAbsDk() / l.dk});
    dP.points.push_back({e, c.MaxAbsDP_D(l) / l.dP_D});
  }
  p.series = {std::move(dk), std::move(dP)};
  p.horizontal.push_back({1.0, "limit", "#000000"});
  if (x.found && x.max_error > 0) {
    p.vertical.push_back({x.max_error, fmt::format("answer {}", ErrorText(x.axis, x.max_error)), "#7f3fbf"});
  }
  p.note = fmt::format("{} cases (every cornea, direction, noise draw); hollow markers: below the axis{}", cases,
                       failed ? fmt::format("; {} failed reconstructions not drawn", failed) : "");
  return plot::RenderScatterSvg(p);
}

}  // namespace

std::vector<std::pair<std::string, std::string>> RenderHarnessOutputs(const HarnessRun& run,
                                                                      const InverseAnswer& answer) {
  std::vector<std::pair<std::string, std::string>> out = {
      {"cases.csv", CasesCsv(run)}, {"summary.json", SummaryJson(run, answer)}, {"table.md", TableMd(run, answer)}};
  if (run.config.HasDistortion()) {
    out.emplace_back("dk_vs_residual.svg", Plot(run, answer, false));
    out.emplace_back("dP_vs_residual.svg", Plot(run, answer, true));
  }
  for (const auto& x : answer.assembly) {
    out.emplace_back(fmt::format("assembly_{}.svg", AssemblyAxisName(x.axis)), AssemblyPlot(run, x));
  }
  return out;
}

std::string HarnessAnswerText(const HarnessRun& run, const InverseAnswer& a) {
  std::string out = fmt::format("harness: {} cases, {} within the limits, {} outside, {} failed\n", run.total_cases,
                                a.cases_within, a.cases_outside, a.cases_failed);
  if (run.config.HasDistortion()) out += "inverse answer: " + AnswerSentence(run, a) + "\n";
  if (run.config.HasDistortion() && a.found) {
    out += fmt::format("  limited by {} in {}\n", a.limited_by, CaseDescription(run, a.limiting_case));
    out += fmt::format("  grid: every case up to {:.4g} um within the limits; smallest residual outside: {:.4g} um\n",
                       a.grid_all_pass_up_to_um, a.grid_first_failure_um);
  }
  for (const auto& f : a.families) {
    out += fmt::format("  {}: {}{:.4g} um ({:.4g} px)\n", DistortionFamilyName(f.family),
                       f.found ? "" : ">= ", f.residual_max_um, f.residual_max_um / run.config.pixel_pitch_um);
  }
  if (!run.config.HasAssembly()) return out;
  out += "assembly answer: " + AssemblySentence(run) + ":\n";
  for (const auto& x : a.assembly) {
    out += fmt::format("  {}: {}", AssemblyAxisName(x.axis), AssemblyAnswerLine(run, x));
    if (x.found) {
      out += fmt::format("; limited by {} in {}; grid: all pass up to {:.4g}, smallest failing {:.4g}", x.limited_by,
                         CaseDescription(run, x.limiting_case), x.grid_all_pass_up_to, x.grid_first_failure);
    }
    out += "\n";
  }
  return out;
}

}  // namespace topocal::harness
