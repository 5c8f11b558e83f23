#include "report/html_parts.h"

#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>

#include "model/camera_model.h"
#include "model/config.h"
#include "plot/svg.h"
#include "plot/svg_charts.h"
#include "topo/reconstruction.h"
#include "util/io.h"
#include "util/sha256.h"
#include "util/version.h"

namespace topocal::report::html {

namespace {

// Map kinds and stages in the order they are shown (docs/unit-record.md names: <case>_<stage>_<map>.png).
constexpr const char* kMapKinds[] = {"axial_power", "tangential_power", "elevation", "height_difference"};

constexpr const char* kMapTitles[] = {"Axial power", "Tangential power", "Elevation above the best-fit sphere", "Height difference"};

struct Quantity {
  const char* key;
  const char* label;  // HTML
  const char* unit;
  int decimals;
};

constexpr Quantity kSphereRows[] = {
    {"rx_mm", "r<sub>x</sub>", "mm", 4},          {"ry_mm", "r<sub>y</sub>", "mm", 4},
    {"kx", "k<sub>x</sub>", "", 4},               {"ky", "k<sub>y</sub>", "", 4},
    {"alpha_deg", "\u03b1", "\u00b0", 3},         {"radius_mm", "radius (r<sub>x</sub> + r<sub>y</sub>)/2", "mm", 4},
    {"radius_error_mm", "radius error", "mm", 4}, {"central_axial_power_D", "mean axial power, central 3 mm", "D", 3},
    {"power_error_D", "power error", "D", 3},     {"pv_tangential_D", "tangential power pv", "D", 3},
    {"pv_axial_D", "axial power pv", "D", 3},     {"spots_indexed", "spots indexed", "", 0},
    {"adequacy_ratio", "model adequacy: slope residual / expected noise", "", 2},
    {"structured_residual_ratio", "model adequacy: structured part / expected noise", "", 2},
};

constexpr Quantity kPaperRows[] = {
    {"rx_mm", "r<sub>x</sub>", "mm", 4},
    {"ry_mm", "r<sub>y</sub>", "mm", 4},
    {"kx", "k<sub>x</sub>", "", 4},
    {"ky", "k<sub>y</sub>", "", 4},
    {"alpha_deg", "\u03b1", "\u00b0", 3},
    {"pv_tangential_D", "tangential power pv", "D", 3},
    {"pv_axial_D", "axial power pv", "D", 3},
    {"height_pv_um", "height error pv", "\u00b5m", 3},
    {"height_rms_um", "height error rms", "\u00b5m", 3},
    {"adequacy_ratio", "model adequacy: slope residual / expected noise", "", 2},
    {"structured_residual_ratio", "model adequacy: structured part / expected noise", "", 2},
};

// Below the sphere's and the paper cornea's tables: how to read the two model-adequacy rows.
std::string AdequacyNote(const UnitRecord& rec) {
  return fmt::format(
      "<p class=\"note adequacy\">Model adequacy: the surface model's slope residual over what {} \u00b5m of "
      "spot-centre noise would leave, and the part of it that neighbouring spots share. Above {} (or {} for the "
      "shared part) the surface model does not represent the spots: uncorrected distortion makes them "
      "non-integrable; after correction both should fall below.</p>\n",
      Sig((rec.config ? rec.config->reconstruction : model::ReconstructionSettings{}).spot_uncertainty_um, 2),
      Sig(topo::kAdequacyWarningRatio, 2), Sig(topo::kStructuredResidualWarningRatio, 2));
}

std::string ValueU(const std::optional<UncertaintyBlock>& block, const char* key, int decimals) {
  if (!block) return "";
  const auto it = block->quantities.find(key);
  if (it == block->quantities.end()) return "";
  // U with two significant digits: a calibration good to 2e-6 mm must not print as "+- 0.0000".
  return Fixed(it->second.mean, decimals) + " \u00b1 " + Sig(it->second.U, 2);
}

std::string Lookup(const StageValues& v, const char* key, int decimals) {
  const auto it = v.find(key);
  return it == v.end() ? "" : Fixed(it->second, decimals);
}

std::string MapsFigure(const UnitRecord& rec, const std::string& case_name) {
  std::string s;
  for (std::size_t m = 0; m < std::size(kMapKinds); ++m) {
    std::string row;
    int present = 0;
    for (const char* stage : {"uncorrected", "corrected"}) {
      const std::string name = fmt::format("{}_{}_{}.png", case_name, stage, kMapKinds[m]);
      const auto it = rec.map_png.find(name);
      row += "<figure class=\"map\">";
      if (it != rec.map_png.end()) {
        ++present;
        row += fmt::format("<img alt=\"{0}\" data-name=\"maps/{0}\" src=\"data:image/png;base64,{1}\">", H(name),
                           Base64(it->second));
      } else {
        row += "<div class=\"nomap\">not in the record</div>";
      }
      row += fmt::format("<figcaption>{}, {}</figcaption></figure>", kMapTitles[m], stage);
    }
    if (present > 0) s += "<div class=\"map-row\">" + row + "</div>\n";
  }
  if (s.empty()) return "<p class=\"note\">The record holds no maps for this case.</p>\n";
  return s;
}

// Signed value of check `id` (the n-th of that id) in a verdict, as |error| is what the check holds; the record's
// signed numbers are read from the record itself below.
const Check* FindCheck(const Verdict& v, const std::string& id, int nth = 0) {
  for (const Check& c : v.checks) {
    if (c.id == id && nth-- == 0) return &c;
  }
  return nullptr;
}

}  // namespace

// The device stage: the calibrated device's parameters from device.json, and the held-out ball and the
// paper cornea measured uncorrected, with the lens calibration only, and through the calibrated device.
std::string DeviceSection(const UnitRecord& rec) {
  const auto& d = *rec.device;
  const auto& cal = d.file.calibration;
  std::string s = "<section id=\"device\" class=\"page-break\"><h2>Device calibration from reference balls: screen "
                  "pose, camera and lens</h2>\n";
  s += "<table class=\"data\"><tr><th>parameter</th><th>value</th><th>U (k = 2)</th><th>nominal</th></tr>\n";
  if (cal.is_object() && cal.contains("parameters") && cal["parameters"].is_object()) {
    for (const auto& [name, p] : cal["parameters"].items()) {
      if (!p.is_object() || !p.contains("value") || !p.contains("stddev") || !p.contains("nominal")) continue;
      s += fmt::format("<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td></tr>\n",
                       H(name), Sig(p["value"].get<double>(), 7), Sig(2.0 * p["stddev"].get<double>(), 2),
                       Sig(p["nominal"].get<double>(), 7));
    }
  }
  s += "</table>\n";
  const auto text = [&](const char* key) {
    return cal.is_object() && cal.contains(key) && cal[key].is_string() ? cal[key].get<std::string>() : std::string();
  };
  if (cal.is_object() && cal.contains("chi2_per_dof") && cal["chi2_per_dof"].is_number()) {
    const bool adequate = cal.value("model_adequate", true);
    s += fmt::format("<p>\u03c7\u00b2/dof {} \u2014 {}.</p>\n", Sig(cal["chi2_per_dof"].get<double>(), 3),
                     adequate ? "the device model describes the ball images"
                              : "<strong>the device model does not describe the ball images</strong>");
  }
  if (!text("gauge").empty()) s += fmt::format("<p class=\"note\">Gauge: {}.</p>\n", H(text("gauge")));
  if (cal.is_object() && cal.contains("notes") && cal["notes"].is_array()) {
    for (const auto& n : cal["notes"]) {
      if (n.is_string()) s += fmt::format("<p class=\"note\">{}</p>\n", H(n.get<std::string>()));
    }
  }
  const auto three_way = [&](const std::map<std::string, StageValues>& stages, const char* key, int decimals,
                             const std::string& truth) {
    std::string row;
    for (const char* st : kThreeWayStages) row += fmt::format("<td class=\"num\">{}</td>", Lookup(stages.at(st), key, decimals));
    return fmt::format("<td class=\"num\">{}</td>{}", truth, row);
  };
  const std::string head = "<tr><th>quantity</th><th>truth</th><th>uncorrected</th><th>lens only</th>"
                           "<th>through the device</th></tr>\n";
  if (!d.held_out.empty()) {
    s += "<div class=\"keep\"><h3>Held-out reference ball (not used in the fit)</h3>\n<table class=\"data\">" + head;
    s += "<tr><td>radius (mm)</td>" + three_way(d.held_out, "radius_mm", 4, Fixed(d.held_out_radius_true_mm, 4)) + "</tr>\n";
    s += "<tr><td>mean axial power, central 3 mm (D)</td>" +
         three_way(d.held_out, "central_axial_power_D", 3, Fixed(d.held_out_power_true_D, 3)) + "</tr>\n";
    s += "</table></div>\n";
  }
  s += "<div class=\"keep\"><h3>Paper cornea imaged through the calibrated unit</h3>\n<table class=\"data\">" + head;
  for (const Quantity& q : kPaperRows) {
    const auto t = rec.paper.truth.find(q.key);
    if (!d.paper.at("device").count(q.key)) continue;
    s += fmt::format("<tr><td>{}{}</td>", q.label, *q.unit ? fmt::format(" ({})", q.unit) : std::string()) +
         three_way(d.paper, q.key, q.decimals, t != rec.paper.truth.end() ? Fixed(t->second, q.decimals) : "") +
         "</tr>\n";
  }
  s += "</table></div>\n<p class=\"note\">Through the device the simulation reproduces the truth by construction; the "
       "other columns are what this unit would report without the device stage (docs/device.md).</p>\n";
  s += "</section>\n";
  return s;
}

// The numbers a service engineer compares between the unit's previous calibration and this one.
std::vector<ComparisonRow> ComparisonRows(const UnitRecord& now, const UnitRecord& prev, const ReportInputs& in) {
  const Verdict vn = Evaluate(now, in.limits, in.budget), vp = Evaluate(prev, in.limits, in.budget);
  using Row = ComparisonRow;
  std::vector<Row> rows;
  rows.push_back({"calibration_rms_px", "calibration RMS", "px", "px", prev.calibration_rms_px, now.calibration_rms_px,
                  {}, {}, 4});
  if (prev.seidel_sigma_per_mm2 && now.seidel_sigma_per_mm2) {
    rows.push_back({"seidel_sigma_per_mm2", "Seidel \u03c3", "mm<sup>\u22122</sup>", "mm^-2", prev.seidel_sigma_per_mm2,
                    now.seidel_sigma_per_mm2, 2 * prev.seidel_sigma_stddev_per_mm2.value_or(0),
                    2 * now.seidel_sigma_stddev_per_mm2.value_or(0), 5});
  }
  const auto sphere = [](const UnitRecord& r, const char* key) -> std::optional<double> {
    if (!r.verification) return std::nullopt;
    return r.verification->corrected.at(key);
  };
  const auto checkU = [](const Verdict& v, const char* id) -> std::optional<double> {
    const Check* c = FindCheck(v, id);
    return c ? c->U : std::nullopt;
  };
  rows.push_back({"sphere_radius_error_mm", "sphere radius error, corrected", "mm", "mm", sphere(prev, "radius_error_mm"),
                  sphere(now, "radius_error_mm"), checkU(vp, "sphere_radius_error_mm"),
                  checkU(vn, "sphere_radius_error_mm"), 4});
  rows.push_back({"sphere_power_error_D", "sphere power error, corrected", "D", "D", sphere(prev, "power_error_D"),
                  sphere(now, "power_error_D"), checkU(vp, "sphere_power_error_D"), checkU(vn, "sphere_power_error_D"),
                  4});
  for (const char* key : {"kx", "ky"}) {
    const auto err = [&](const UnitRecord& r) { return r.paper.corrected.at(key) - r.paper.truth.at(key); };
    const auto u = [&](const UnitRecord& r) -> std::optional<double> {
      if (!r.paper.uncertainty || !r.paper.uncertainty->quantities.count(key)) return std::nullopt;
      return r.paper.uncertainty->quantities.at(key).U;
    };
    rows.push_back({fmt::format("paper_{}_error", key),
                    fmt::format("paper cornea k<sub>{}</sub> \u2212 truth, corrected", key + 1), "", "", err(prev),
                    err(now), u(prev), u(now), 4});
  }
  return rows;
}

// The unit's previous calibration beside this one: the numbers, their change, and whether the change exceeds the U
// of the difference.
std::string PreviousComparison(const UnitRecord& now, const UnitRecord& prev, const ReportInputs& in) {
  const Verdict vn = Evaluate(now, in.limits, in.budget), vp = Evaluate(prev, in.limits, in.budget);
  const std::vector<ComparisonRow> rows = ComparisonRows(now, prev, in);
  std::string s = "<section id=\"previous\" class=\"keep\"><h2>Comparison with the previous calibration</h2>\n";
  s += fmt::format("<p>Previous record {} (created {}, verdict under these limits: <strong>{}</strong>); this record "
                   "created {} (<strong>{}</strong>).</p>\n",
                   H(prev.directory), H(prev.created_utc), vp.pass ? "PASS" : "FAIL", H(now.created_utc),
                   vn.pass ? "PASS" : "FAIL");
  s += "<table class=\"data\" id=\"previous-table\"><tr><th>quantity</th><th>previous</th><th>now</th><th>change</th>"
       "<th>U of the change (k = 2)</th><th></th></tr>\n";
  for (const ComparisonRow& r : rows) {
    const std::string unit = r.unit.empty() ? "" : " " + r.unit;
    if (!r.prev || !r.now) {
      s += fmt::format("<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td colspan=\"3\" "
                       "class=\"note\">not in both records</td></tr>\n",
                       r.label, r.prev ? Sig(*r.prev, r.digits) + unit : "\u2014",
                       r.now ? Sig(*r.now, r.digits) + unit : "\u2014");
      continue;
    }
    const double change = *r.Change();
    std::string u_text = "\u2014", flag;
    if (const auto U = r.ChangeU()) {
      u_text = Sig(*U, 2) + unit;
      flag = std::abs(change) > *U ? "changed beyond U" : "within U";
    }
    s += fmt::format("<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
                     "<td class=\"num\">{}</td><td class=\"flag\">{}</td></tr>\n",
                     r.label, Sig(*r.prev, r.digits) + unit, Sig(*r.now, r.digits) + unit,
                     (change > 0 ? "+" : "") + Sig(change, 3) + unit, u_text, flag);
  }
  s += "</table></section>\n";
  return s;
}

// The heading of the column of values with the calibration's U: with linear propagation the value is the corrected
// one itself, with Monte Carlo the draws' mean.
std::string UncertaintyHeading(const UnitRecord& rec) {
  return rec.settings_uncertainty.method == pipeline::UncertaintySetting::Method::kMonteCarlo
             ? "corrected, Monte Carlo mean \u00b1 U (k = 2)"
             : "corrected \u00b1 U (k = 2)";
}

// The reference sphere before and after correction, against its certified radius.
std::string SphereSection(const UnitRecord& rec) {
  std::string s;
  s += "<section id=\"sphere\" class=\"page-break\"><h2>Reference sphere: before and after correction</h2>\n";
  if (rec.verification) {
    const SphereVerification& v = *rec.verification;
    s += fmt::format("<p>Image {}; true radius {} mm, true power {} D (n<sub>k</sub> = {}).</p>\n", H(v.image),
                     Fixed(v.radius_true_mm, 4), Fixed(v.power_true_D, 3), Sig(v.keratometric_index, 5));
    s += "<table class=\"data\"><tr><th>quantity</th><th>truth</th><th>uncorrected</th><th>corrected</th><th>" +
         UncertaintyHeading(rec) + "</th></tr>\n";
    constexpr const char* kUndefined = "<span class=\"undefined\">undefined</span>";
    for (const Quantity& q : kSphereRows) {
      if (std::string_view(q.key) == "alpha_deg") {
        // A sphere has no principal axes: any alpha fits it, and the fitted one only orients noise-level
        // astigmatism. Printed as undefined; the fitted values are given below the table.
        s += fmt::format("<tr data-quantity=\"alpha_deg\"><td>{} ({})</td><td class=\"num\">{}</td><td "
                         "class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td></tr>\n",
                         q.label, q.unit, kUndefined, kUndefined, kUndefined, kUndefined);
        continue;
      }
      std::string truth;
      if (std::string_view(q.key) == "rx_mm" || std::string_view(q.key) == "ry_mm" ||
          std::string_view(q.key) == "radius_mm") {
        truth = Fixed(v.radius_true_mm, q.decimals);
      } else if (std::string_view(q.key) == "kx" || std::string_view(q.key) == "ky") {
        truth = Fixed(0, q.decimals);
      } else if (std::string_view(q.key) == "central_axial_power_D") {
        truth = Fixed(v.power_true_D, q.decimals);
      }
      s += fmt::format("<tr><td>{}{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
                       "<td class=\"num\">{}</td></tr>\n",
                       q.label, *q.unit ? fmt::format(" ({})", q.unit) : std::string(), truth,
                       Lookup(v.uncorrected, q.key, q.decimals), Lookup(v.corrected, q.key, q.decimals),
                       ValueU(v.uncertainty, q.key, q.decimals));
    }
    s += "</table>\n";
    s += fmt::format("<p class=\"note\" id=\"alpha-note\">\u03b1 (the axis of r<sub>x</sub>) is undefined for a "
                     "sphere: r<sub>x</sub> = r<sub>y</sub> and every axis fits equally. The biconic fit returned {}\u00b0 "
                     "uncorrected and {}\u00b0 corrected for |r<sub>x</sub> \u2212 r<sub>y</sub>| = {} and {} mm: the "
                     "orientation of noise, not of the surface.</p>\n",
                     Lookup(v.uncorrected, "alpha_deg", 1), Lookup(v.corrected, "alpha_deg", 1),
                     Sig(std::abs(v.uncorrected.at("rx_mm") - v.uncorrected.at("ry_mm")), 2),
                     Sig(std::abs(v.corrected.at("rx_mm") - v.corrected.at("ry_mm")), 2));
    s += AdequacyNote(rec);
  } else {
    s += "<p class=\"note\">No reference sphere was given: the unit is not verified.</p>\n";
  }
  s += MapsFigure(rec, "sphere");
  s += "</section>\n";
  return s;
}

// The paper's biconic cornea simulated through this camera, before and after correction.
std::string PaperSection(const UnitRecord& rec) {
  std::string s;
  s += "<section id=\"paper\" class=\"page-break\"><h2>Paper biconic cornea (simulated through this camera): before "
       "and after correction</h2>\n";
  s += "<table class=\"data\"><tr><th>quantity</th><th>truth</th><th>uncorrected</th><th>corrected</th>"
       "<th>corrected \u2212 truth</th><th>" + UncertaintyHeading(rec) + "</th></tr>\n";
  for (const Quantity& q : kPaperRows) {
    const auto t = rec.paper.truth.find(q.key);
    const bool has_truth = t != rec.paper.truth.end();
    s += fmt::format("<tr><td>{}{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
                     "<td class=\"num\">{}</td><td class=\"num\">{}</td></tr>\n",
                     q.label, *q.unit ? fmt::format(" ({})", q.unit) : std::string(),
                     has_truth ? Fixed(t->second, q.decimals) : "",
                     Lookup(rec.paper.uncorrected, q.key, q.decimals), Lookup(rec.paper.corrected, q.key, q.decimals),
                     has_truth ? Fixed(rec.paper.corrected.at(q.key) - t->second, q.decimals) : "",
                     ValueU(rec.paper.uncertainty, q.key, q.decimals));
  }
  s += "</table>\n";
  s += AdequacyNote(rec);
  s += MapsFigure(rec, "paper");
  s += "</section>\n";
  return s;
}

}  // namespace topocal::report::html
