#include "pipeline/harness_report.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "model/version.h"
#include "pipeline/svg_plot.h"

namespace topocal::pipeline {
namespace {

using nlohmann::json;

const char* kFamilyColours[] = {"#1f77b4", "#d62728", "#2ca02c"};

std::string Num(double v) { return fmt::format("{:.9g}", v); }

const char* MapsName(const HarnessRun& run) { return run.config.limits.tangential_map ? "axial+tangential" : "axial"; }

std::string CasesCsv(const HarnessRun& run) {
  std::string out =
      "case,cornea,family,coefficient,calibration_error,noise_px,draw,seed,status,residual_max_um,residual_rms_um,"
      "residual_max_px,residual_rms_px,spots_used,undistort_failures,dk_x,dk_y,dr_x_mm,dr_y_mm,dP_axial_max_D,"
      "dP_tangential_max_D,dpv_axial_D,dpv_tangential_D,compared_radius_mm,within_limits\n";
  const double pitch = run.config.pixel_pitch_um;
  for (const auto& c : run.cases) {
    const auto& s = c.spec;
    out += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},", s.index, run.config.corneas[s.cornea].name,
                       DistortionFamilyName(s.family), Num(s.coefficient), Num(s.calibration_error), Num(s.noise_px),
                       s.draw, s.seed, c.ok ? "ok" : "failed", Num(c.residual_max_um), Num(c.residual_rms_um),
                       Num(c.residual_max_um / pitch), Num(c.residual_rms_um / pitch), c.spots_used,
                       c.undistort_failures);
    if (c.ok) {
      out += fmt::format("{},{},{},{},{},{},{},{},{},{}\n", Num(c.dk_x), Num(c.dk_y), Num(c.dr_x_mm), Num(c.dr_y_mm),
                         Num(c.dP_axial_max_D), Num(c.dP_tangential_max_D), Num(c.dpv_axial_D),
                         Num(c.dpv_tangential_D), Num(c.compared_radius_mm),
                         LimitUtilisation(c, run.config.limits) <= 1 ? 1 : 0);
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
    families[DistortionFamilyName(f.family)] = {{"found", f.found}, {"residual_max_um", f.residual_max_um},
                                                {"residual_max_px", f.residual_max_um / run.config.pixel_pitch_um}};
  }
  j["per_family"] = families;
  return j;
}

std::string SummaryJson(const HarnessRun& run, const InverseAnswer& a) {
  json j;
  j["format"] = "topocal-harness-summary";
  j["topocal_version"] = kVersion;
  j["config_sha256"] = run.config_sha256;
  j["config"] = json::parse(CanonicalHarnessJson(run.config));
  j["cases"] = {{"total", run.total_cases}, {"within_limits", a.cases_within}, {"outside_limits", a.cases_outside},
                {"failed", a.cases_failed}};
  j["limits"] = {{"dk", run.config.limits.dk}, {"dP_D", run.config.limits.dP_D}, {"dP_maps", MapsName(run)}};
  j["answer"] = AnswerJson(run, a);
  json truth = json::array();
  for (const auto& t : run.truth) {
    truth.push_back({{"cornea", t.cornea},
                     {"fit", {{"rx_mm", t.fit.rx_mm}, {"ry_mm", t.fit.ry_mm}, {"kx", t.fit.kx}, {"ky", t.fit.ky},
                              {"alpha_deg", t.fit.alpha_deg}}},
                     {"covered_radius_mm", t.covered_radius_mm},
                     {"spot_field_radius_mm", t.spot_field_radius_mm},
                     {"spots", t.spots},
                     {"pv_axial_D", t.pv_axial_D},
                     {"pv_tangential_D", t.pv_tangential_D}});
  }
  j["truth"] = truth;
  if (a.limiting_case >= 0) {
    const auto& c = run.cases[static_cast<size_t>(a.limiting_case)];
    j["limiting_case"] = {{"case", c.spec.index},
                          {"cornea", run.config.corneas[c.spec.cornea].name},
                          {"family", DistortionFamilyName(c.spec.family)},
                          {"coefficient", c.spec.coefficient},
                          {"calibration_error", c.spec.calibration_error},
                          {"noise_px", c.spec.noise_px},
                          {"residual_max_um", c.residual_max_um},
                          {"dk", c.MaxAbsDk()},
                          {"dP_D", c.MaxAbsDP_D(run.config.limits)}};
  }
  return j.dump(2) + "\n";
}

std::string AnswerSentence(const HarnessRun& run, const InverseAnswer& a) {
  const auto& l = run.config.limits;
  if (!a.found) {
    return fmt::format("every case is within |dk| <= {:g} and |dP| <= {:g} D ({}) up to the largest residual tested, "
                       "{:.4g} um ({:.4g} px, |sigma| {:.3g} mm^-2 equivalent): the answer is at least that",
                       l.dk, l.dP_D, MapsName(run), a.residual_max_um, a.residual_max_px, a.sigma_equivalent_per_mm2);
  }
  if (a.noise_alone_exceeds && a.residual_max_um == 0) {
    return fmt::format("none: the spot-position noise alone puts a case outside |dk| <= {:g} or |dP| <= {:g} D ({})",
                       l.dk, l.dP_D, MapsName(run));
  }
  return fmt::format("largest residual distortion keeping every case within |dk| <= {:g} and |dP| <= {:g} D ({}): "
                     "{:.4g} um at the detection plane = {:.4g} px = |sigma| {:.3g} mm^-2 equivalent",
                     l.dk, l.dP_D, MapsName(run), a.residual_max_um, a.residual_max_px, a.sigma_equivalent_per_mm2);
}

std::string CaseDescription(const HarnessRun& run, int index) {
  const auto& c = run.cases[static_cast<size_t>(index)];
  return fmt::format("case {}: cornea {}, {} = {:.4g}, calibration error {:+g}, noise {:g} px draw {}: residual "
                     "{:.4g} um, |dk| {:.4g}, |dP| {:.4g} D{}",
                     c.spec.index, run.config.corneas[c.spec.cornea].name, DistortionFamilyName(c.spec.family),
                     c.spec.coefficient, c.spec.calibration_error, c.spec.noise_px, c.spec.draw, c.residual_max_um,
                     c.MaxAbsDk(), c.MaxAbsDP_D(run.config.limits), c.ok ? "" : " (reconstruction failed: " + c.failure + ")");
}

std::string TableMd(const HarnessRun& run, const InverseAnswer& a) {
  const auto& cfg = run.config;
  std::string md = "# Residual-distortion harness\n\n";
  md += fmt::format("Configuration SHA-256 `{}`; {} cases; limits |dk| <= {:g}, |dP| <= {:g} D ({} maps).\n\n",
                    run.config_sha256, run.total_cases, cfg.limits.dk, cfg.limits.dP_D, MapsName(run));
  md += "**Inverse answer:** " + AnswerSentence(run, a) + ".\n\n";
  if (a.found) {
    md += fmt::format("Grid bounds: every tested case with a residual up to {:.4g} um is within the limits; the "
                      "smallest residual of a case outside them is {:.4g} um. Limiting {} ({}).\n\n",
                      a.grid_all_pass_up_to_um, a.grid_first_failure_um, CaseDescription(run, a.limiting_case),
                      a.limited_by);
  }
  md += "| family | largest tolerable residual (um) | (px) |\n|---|---:|---:|\n";
  for (const auto& f : a.families) {
    md += fmt::format("| {} | {}{:.4g} | {:.4g} |\n", DistortionFamilyName(f.family), f.found ? "" : ">= ",
                      f.residual_max_um, f.residual_max_um / cfg.pixel_pitch_um);
  }
  md += "\n## Truth reconstructions (undistorted, noise-free spots)\n\n";
  md += "| cornea | r_x (mm) | r_y (mm) | k_x | k_y | alpha (deg) | covered radius (mm) | spots |\n"
        "|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& t : run.truth) {
    md += fmt::format("| {} | {:.5f} | {:.5f} | {:.5f} | {:.5f} | {:.4f} | {:.3f} | {} |\n", t.cornea, t.fit.rx_mm,
                      t.fit.ry_mm, t.fit.kx, t.fit.ky, t.fit.alpha_deg, t.covered_radius_mm, t.spots);
  }
  md += "\n## Cases by distortion and calibration error\n\nWorst over corneas, noise levels and draws. "
        "e = -1 is no correction.\n\n";
  md += "| family | coefficient | e | residual max (um) | (px) | max \\|dk\\| | max \\|dP\\| (D) | within limits |\n"
        "|---|---:|---:|---:|---:|---:|---:|---:|\n";
  struct Row {
    double residual = 0, dk = 0, dP = 0;
    int within = 0, total = 0, failed = 0;
  };
  std::map<std::tuple<int, double, double>, Row> rows;
  for (const auto& c : run.cases) {
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
  ScatterPlot p;
  p.title = power ? "Power-map error against residual distortion" : "Conic-constant error against residual distortion";
  p.x_label = "residual distortion, max displacement over the spot field (um, detection plane)";
  p.y_label = power ? fmt::format("max |P - P_truth| over the disc, {} map{} (D)", MapsName(run),
                                   run.config.limits.tangential_map ? "s" : "")
                    : "max |k - k_truth| of k_x, k_y";
  int failed = 0;
  for (const DistortionFamily f : kDistortionFamilies) {
    if (run.config.Coefficients(f).empty()) continue;
    PlotSeries s;
    s.label = DistortionFamilyName(f);
    s.colour = kFamilyColours[static_cast<int>(f)];
    for (const auto& c : run.cases) {
      if (c.spec.family != f) continue;
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
  p.horizontal.push_back({power ? run.config.limits.dP_D : run.config.limits.dk,
                          power ? fmt::format("limit {:g} D", run.config.limits.dP_D)
                                : fmt::format("limit {:g}", run.config.limits.dk),
                          "#000000"});
  if (a.found && a.residual_max_um > 0) {
    p.vertical.push_back({a.residual_max_um, fmt::format("answer {:.3g} um", a.residual_max_um), "#7f3fbf"});
  }
  p.note = fmt::format("{} cases; hollow markers: below the axis (no residual, or error below the axis){}",
                       run.total_cases, failed ? fmt::format("; {} failed reconstructions not drawn", failed) : "");
  return RenderScatterSvg(p);
}

}  // namespace

std::vector<std::pair<std::string, std::string>> RenderHarnessOutputs(const HarnessRun& run, const InverseAnswer& answer) {
  return {{"cases.csv", CasesCsv(run)},
          {"summary.json", SummaryJson(run, answer)},
          {"table.md", TableMd(run, answer)},
          {"dk_vs_residual.svg", Plot(run, answer, false)},
          {"dP_vs_residual.svg", Plot(run, answer, true)}};
}

std::string HarnessAnswerText(const HarnessRun& run, const InverseAnswer& a) {
  std::string out = fmt::format("harness: {} cases, {} within the limits, {} outside, {} failed\n", run.total_cases,
                                a.cases_within, a.cases_outside, a.cases_failed);
  out += "inverse answer: " + AnswerSentence(run, a) + "\n";
  if (a.found) {
    out += fmt::format("  limited by {} in {}\n", a.limited_by, CaseDescription(run, a.limiting_case));
    out += fmt::format("  grid: every case up to {:.4g} um within the limits; smallest residual outside: {:.4g} um\n",
                       a.grid_all_pass_up_to_um, a.grid_first_failure_um);
  }
  for (const auto& f : a.families) {
    out += fmt::format("  {}: {}{:.4g} um ({:.4g} px)\n", DistortionFamilyName(f.family), f.found ? "" : ">= ",
                       f.residual_max_um, f.residual_max_um / run.config.pixel_pitch_um);
  }
  return out;
}

}  // namespace topocal::pipeline
