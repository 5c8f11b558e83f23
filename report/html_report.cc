#include "report/html_report.h"

#include <fmt/format.h>
#include <openssl/evp.h>

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

namespace topocal::report {

using plot::Arrow;
using plot::Bar;
using plot::CellField;
using plot::EscapeXml;
using plot::PixelRegion;
using plot::QuiverOptions;
using plot::SvgBarChart;
using plot::SvgQuiver;
namespace {

// Grids of the distortion-field plot: coloured cells (magnitude) and arrows, over the whole image.
constexpr int kFieldCellsAcross = 48;
constexpr int kFieldArrowsAcross = 16;
// The residual plot zooms on the corners when they span less than this fraction of the image in both directions,
// with this relative margin around them.
constexpr double kZoomBelowFraction = 0.5;
constexpr double kZoomMargin = 0.15;
// Map kinds and stages in the order they are shown (docs/unit-record.md names: <case>_<stage>_<map>.png).
constexpr const char* kMapKinds[] = {"axial_power", "tangential_power", "elevation", "height_difference"};
constexpr const char* kMapTitles[] = {"Axial power", "Tangential power", "Elevation above the best-fit sphere", "Height difference"};

std::string H(std::string_view s) { return EscapeXml(s); }

// Fixed decimals, never "nan", never "-0.000".
std::string Fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "\u2014";
  std::string s = fmt::format("{:.{}f}", v, decimals);
  if (s.front() == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);
  return s;
}
std::string Sig(double v, int digits = 6) {
  if (!std::isfinite(v)) return "\u2014";
  if (v == 0) return "0";
  return fmt::format("{:.{}g}", v, digits);
}

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
    s += "<h3>Held-out reference ball (not used in the fit)</h3>\n<table class=\"data\">" + head;
    s += "<tr><td>radius (mm)</td>" + three_way(d.held_out, "radius_mm", 4, Fixed(d.held_out_radius_true_mm, 4)) + "</tr>\n";
    s += "<tr><td>mean axial power, central 3 mm (D)</td>" +
         three_way(d.held_out, "central_axial_power_D", 3, Fixed(d.held_out_power_true_D, 3)) + "</tr>\n";
    s += "</table>\n";
  }
  s += "<h3>Paper cornea imaged through the calibrated unit</h3>\n<table class=\"data\">" + head;
  for (const Quantity& q : kPaperRows) {
    const auto t = rec.paper.truth.find(q.key);
    if (!d.paper.at("device").count(q.key)) continue;
    s += fmt::format("<tr><td>{}{}</td>", q.label, *q.unit ? fmt::format(" ({})", q.unit) : std::string()) +
         three_way(d.paper, q.key, q.decimals, t != rec.paper.truth.end() ? Fixed(t->second, q.decimals) : "") +
         "</tr>\n";
  }
  s += "</table>\n<p class=\"note\">Through the device the simulation reproduces the truth by construction; the "
       "other columns are what this unit would report without the device stage (docs/device.md).</p>\n";
  s += "</section>\n";
  return s;
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

// Residual vectors live where the target was. A single view at the cornea position covers a small patch of the
// image: the plot then shows that patch (with a margin) so the vectors can be read; the caption says which part.
std::optional<PixelRegion> ResidualRegion(const UnitRecord& rec) {
  if (rec.residuals.empty()) return std::nullopt;
  double x0 = rec.residuals.front().x_px, x1 = x0, y0 = rec.residuals.front().y_px, y1 = y0;
  for (const CornerResidualRow& r : rec.residuals) {
    x0 = std::min(x0, r.x_px);
    x1 = std::max(x1, r.x_px);
    y0 = std::min(y0, r.y_px);
    y1 = std::max(y1, r.y_px);
  }
  const double w = rec.calibration_width_px, h = rec.calibration_height_px;
  if (x1 - x0 > kZoomBelowFraction * w || y1 - y0 > kZoomBelowFraction * h) return std::nullopt;
  // Keep the image's aspect ratio so the plot has the same shape as the full-frame ones.
  const double half_w = std::max(0.5 * (x1 - x0), 0.5 * (y1 - y0) * w / h) * (1 + kZoomMargin);
  const double half_h = half_w * h / w;
  const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
  return PixelRegion{cx - half_w, cy - half_h, 2 * half_w, 2 * half_h};
}

// The part of the image the distortion plot covers: the measurement's field (about the principal point, holding
// the field radius, widened to the image's aspect) when the record gives it, else the corners' region, else the
// whole image. A strong Seidel k1 fitted for a small central field means nothing at the sensor's corners.
PixelRegion FieldRegion(const UnitRecord& rec, const std::optional<PixelRegion>& corners) {
  const double w = rec.calibration_width_px, h = rec.calibration_height_px;
  if (rec.field_radius_px) {
    const double half_h = std::min(*rec.field_radius_px * (1 + kZoomMargin), 0.5 * h);
    const double half_w = half_h * w / h;
    return {rec.calibration.camera.cx_px - half_w, rec.calibration.camera.cy_px - half_h, 2 * half_w, 2 * half_h};
  }
  if (corners) return *corners;
  return {-0.5, -0.5, w, h};
}

struct DistortionPlot {
  std::string svg;
  double max_displacement_px = 0;
};

DistortionPlot DistortionField(const model::CameraModel& cam, const PixelRegion& region, bool whole_image,
                               std::optional<double> field_radius_px) {
  const double in[4] = {cam.fx_px, cam.fy_px, cam.cx_px, cam.cy_px};
  // Where an ideal (pinhole) image point p lands through the calibrated lens, minus p.
  auto displacement = [&](double x, double y) {
    const double u[2] = {(x - cam.cx_px) / cam.fx_px, (y - cam.cy_px) / cam.fy_px};
    double px[2];
    model::CameraModel::NormalizedToPixel(in, cam.dist.data(), cam.distortion_centre.data(), u, px);
    const Eigen::Vector2d d(px[0] - x, px[1] - y);
    if (!d.allFinite()) throw std::runtime_error("the calibration's distortion is not finite over the image");
    return d;
  };
  DistortionPlot plot;
  CellField field;
  field.cols = kFieldCellsAcross;
  field.rows = std::max(1, static_cast<int>(std::lround(kFieldCellsAcross * region.height_px / region.width_px)));
  field.label = "|displacement| (px)";
  // With the measurement field given, cells beyond its disc have no data: the colour bar and the caption's largest
  // displacement then speak of the same region.
  for (int r = 0; r < field.rows; ++r) {
    for (int c = 0; c < field.cols; ++c) {
      const double x = region.x_px + (c + 0.5) * region.width_px / field.cols;
      const double y = region.y_px + (r + 0.5) * region.height_px / field.rows;
      const bool outside = field_radius_px && std::hypot(x - cam.cx_px, y - cam.cy_px) > *field_radius_px;
      field.values.push_back(outside ? std::numeric_limits<double>::quiet_NaN() : displacement(x, y).norm());
    }
  }
  // The largest displacement where it matters: within the measurement field's disc when the record gives it
  // (rings out to its radius; the plotted rectangle's corners lie beyond the field and are not measured on), else
  // on the region's border, where the extreme of a radial field is; both sampled densely.
  constexpr int kBorderSamples = 256;
  if (field_radius_px) {
    constexpr int kRings = 16;
    for (int k = 1; k <= kRings; ++k) {
      const double rho = *field_radius_px * k / kRings;
      for (int i = 0; i < kBorderSamples; ++i) {
        const double t = 2 * M_PI * i / kBorderSamples;
        plot.max_displacement_px = std::max(
            plot.max_displacement_px, displacement(cam.cx_px + rho * std::cos(t), cam.cy_px + rho * std::sin(t)).norm());
      }
    }
  }
  for (int i = 0; !field_radius_px && i <= kBorderSamples; ++i) {
    const double t = static_cast<double>(i) / kBorderSamples;
    for (const auto& [x, y] : {std::pair{region.x_px + t * region.width_px, region.y_px},
                               std::pair{region.x_px + t * region.width_px, region.y_px + region.height_px},
                               std::pair{region.x_px, region.y_px + t * region.height_px},
                               std::pair{region.x_px + region.width_px, region.y_px + t * region.height_px}}) {
      plot.max_displacement_px = std::max(plot.max_displacement_px, displacement(x, y).norm());
    }
  }
  std::vector<Arrow> arrows;
  const int arrows_down =
      std::max(1, static_cast<int>(std::lround(kFieldArrowsAcross * region.height_px / region.width_px)));
  for (int r = 0; r < arrows_down; ++r) {
    for (int c = 0; c < kFieldArrowsAcross; ++c) {
      const double x = region.x_px + (c + 0.5) * region.width_px / kFieldArrowsAcross;
      const double y = region.y_px + (r + 0.5) * region.height_px / arrows_down;
      if (field_radius_px && std::hypot(x - cam.cx_px, y - cam.cy_px) > *field_radius_px) continue;  // not measured
      const Eigen::Vector2d d = displacement(x, y);
      arrows.push_back({x, y, d.x(), d.y(), false});
    }
  }
  field.value_max = plot.max_displacement_px;  // the caption's number is the bar's top
  QuiverOptions o;
  o.image_width_px = cam.width_px;
  o.image_height_px = cam.height_px;
  if (!whole_image) o.region = region;
  o.title = "Distortion field of the calibrated model (distorted \u2212 ideal)";
  o.background = std::move(field);
  plot.svg = SvgQuiver(arrows, o);
  return plot;
}

constexpr const char* kCss = R"css(
:root { --pass: #2e7d32; --fail: #c62828; --ink: #1a1a1a; --rule: #c8c8c8; }
* { box-sizing: border-box; }
html { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
body { font-family: "DejaVu Sans", Arial, sans-serif; color: var(--ink); margin: 0; font-size: 10.5pt; line-height: 1.35; }
main { max-width: 190mm; margin: 0 auto; padding: 8mm 6mm; }
h1 { font-size: 17pt; margin: 0 0 2mm 0; }
h2 { font-size: 13pt; border-bottom: 1.5px solid var(--ink); padding-bottom: 1mm; margin: 7mm 0 3mm 0; }
h3 { font-size: 11pt; margin: 5mm 0 2mm 0; }
table.data { border-collapse: collapse; width: 100%; margin: 2mm 0; }
table.data td { overflow-wrap: break-word; }  /* a token breaks only when it cannot fit a line of its own */
table.data th, table.data td { border-bottom: 1px solid var(--rule); padding: 1mm 2mm; text-align: left; vertical-align: top; }
table.data th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
.hash { font-family: "DejaVu Sans Mono", monospace; font-size: 7.5pt; word-break: break-all; }
.banner { font-size: 20pt; font-weight: bold; color: #fff; padding: 4mm 6mm; margin: 3mm 0; border-radius: 2mm; }
.banner.pass { background: var(--pass); }
.banner.fail { background: var(--fail); }
.banner small { display: block; font-size: 10pt; font-weight: normal; }
ul.failed { color: var(--fail); font-weight: bold; margin: 0 0 3mm 0; }
td.pass { color: var(--pass); font-weight: bold; }
td.fail { color: var(--fail); font-weight: bold; }
.report-id { font-family: "DejaVu Sans Mono", monospace; }
.note { color: #555; font-size: 9pt; }
svg.plot { width: 100%; height: auto; display: block; margin: 2mm 0; }
figure { margin: 0; }
.map-row { display: flex; gap: 4mm; margin: 2mm 0; break-inside: avoid; }
.map-row figure { flex: 1 1 0; text-align: center; }
.map-row img { width: 100%; height: auto; border: 1px solid var(--rule); }
.nomap { border: 1px dashed var(--rule); padding: 20mm 2mm; color: #777; }
figcaption { font-size: 9pt; color: #444; }
.keep { break-inside: avoid; }
.print-header, .print-footer { display: none; }
table.page-frame { width: 100%; border-collapse: collapse; }
table.page-frame > thead td, table.page-frame > tfoot td, table.page-frame > tbody > tr > td { padding: 0; }
@page { size: A4; margin: 10mm 10mm 12mm 10mm;
  @bottom-right { content: "Page " counter(page) " of " counter(pages); font-family: "DejaVu Sans", Arial, sans-serif;
                  font-size: 8pt; color: #333; } }
table.budget td, table.budget th { font-size: 9pt; }
.signoff td.blank { height: 11mm; border-bottom: 1px solid var(--ink); }
.undefined { color: #555; font-style: italic; }
td.flag { white-space: nowrap; }
@media print {
  body { font-size: 9.5pt; }
  main { max-width: none; padding: 0; }
  .print-header, .print-footer { display: block; position: fixed; left: 0; right: 0; font-size: 8pt; color: #333;
                                 background: #fff; }
  .print-header { top: 0; border-bottom: 1px solid var(--rule); padding-bottom: 1mm; }
  .print-footer { bottom: 0; border-top: 1px solid var(--rule); padding-top: 1mm; }
  .header-space { height: 9mm; }
  .footer-space { height: 8mm; }
  .page-break { break-before: page; }
  h2, h3 { break-after: avoid; }
  svg.plot, table.data tr, .banner { break-inside: avoid; }
}
)css";

// Signed value of check `id` (the n-th of that id) in a verdict, as |error| is what the check holds; the record's
// signed numbers are read from the record itself below.
const Check* FindCheck(const Verdict& v, const std::string& id, int nth = 0) {
  for (const Check& c : v.checks) {
    if (c.id == id && nth-- == 0) return &c;
  }
  return nullptr;
}

// One quantity of the unit's previous calibration beside this one (the report's table and its JSON).
struct ComparisonRow {
  std::string id, label, unit;  // label and unit as HTML
  std::string plain_unit;       // the unit in the JSON
  std::optional<double> prev, now, U_prev, U_now;
  int digits;
  // The change, and the U of a difference, sqrt(U_prev^2 + U_now^2) (k = 2, independent calibrations).
  std::optional<double> Change() const { return prev && now ? std::optional(*now - *prev) : std::nullopt; }
  std::optional<double> ChangeU() const {
    return U_prev && U_now ? std::optional(std::hypot(*U_prev, *U_now)) : std::nullopt;
  }
};

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

// The budget of each check whose U has more than one input: every contribution, its share of u_c^2, the total.
std::string BudgetTables(const Verdict& v) {
  std::string s;
  for (const Check& c : v.checks) {
    if (c.budget.size() < 2 || !c.U) continue;
    const double uc = CombinedStandardUncertainty(c.budget);
    const std::string unit = c.unit.empty() ? "" : " " + c.unit;
    s += fmt::format("<h3>Uncertainty budget: {}</h3>\n<table class=\"data budget\" data-budget=\"{}\"><tr>"
                     "<th>input</th><th>source</th><th>u (k = 1)</th><th>share of u<sub>c</sub><sup>2</sup></th></tr>\n",
                     H(c.what), H(c.id));
    for (const BudgetTerm& t : c.budget) {
      s += fmt::format("<tr><td>{}</td><td class=\"note\">{}</td><td class=\"num\">{}</td><td class=\"num\">{} %"
                       "</td></tr>\n",
                       H(t.name), H(t.source), Sig(t.u, 3) + unit,
                       Fixed(uc > 0 ? 100.0 * t.u * t.u / (uc * uc) : 0.0, 1));
    }
    s += fmt::format("<tr><th>combined</th><td class=\"note\">u<sub>c</sub> = \u221a(\u03a3 u<sup>2</sup>), inputs "
                     "independent</td><td class=\"num\">{}</td><td class=\"num\">100 %</td></tr>\n",
                     Sig(uc, 3) + unit);
    s += fmt::format("<tr><th>expanded</th><td class=\"note\">U = 2 u<sub>c</sub> (k = 2)</td><td class=\"num\" "
                     "data-U=\"{}\">{}</td><td></td></tr>\n</table>\n",
                     H(c.id), Sig(*c.U, 3) + unit);
  }
  s += "<p class=\"note\">The paper-cornea checks are a simulation (truth exact, images noise-free): their U is the "
       "calibration's alone.</p>\n";
  return s;
}

constexpr const char* kImageCheckScript = R"js(
window.addEventListener('load', function () {
  var images = document.images, decoded = 0;
  for (var i = 0; i < images.length; ++i) {
    if (images[i].complete && images[i].naturalWidth > 0) ++decoded;
  }
  document.documentElement.setAttribute('data-images-decoded', decoded + '/' + images.length);
});
)js";

}  // namespace

std::string Base64(std::string_view bytes) {
  if (bytes.empty()) return {};
  // OpenSSL's encoder: EVP_EncodeBlock writes the RFC 4648 alphabet with padding and no line breaks (unlike
  // EVP_EncodeUpdate, which breaks lines every 64 characters), plus a NUL. Its length argument is an int.
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()) / 4 * 3) {
    throw std::length_error(fmt::format("base64: {} bytes is more than one block can encode", bytes.size()));
  }
  std::string out(4 * ((bytes.size() + 2) / 3) + 1, '\0');
  const int written = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                      reinterpret_cast<const unsigned char*>(bytes.data()), static_cast<int>(bytes.size()));
  out.resize(static_cast<std::size_t>(written));
  return out;
}

void ReportInputs::Validate(const UnitRecord& record) const {
  std::string why;
  if (!budget.IsValid(&why)) throw util::InputError("--ball-radius-U-mm: " + why);
  if (previous && previous->serial != record.serial) {
    throw util::InputError(fmt::format("{}: the previous record is of unit {}, not {}", previous->directory,
                                       previous->serial, record.serial));
  }
  if (previous && previous->unit_json_sha256 == record.unit_json_sha256) {
    throw util::InputError(
        fmt::format("{}: the previous record is the same record as {}", previous->directory, record.directory));
  }
}

std::string ReportIdText(const UnitRecord& record, const ReportInputs& in) {
  const SignOff& so = in.sign_off;
  return fmt::format(
      "topocal-report-id 1\nunit_json_sha256={}\nlimits={}\nball_radius_U_mm={}\noperator={}\nstation={}\n"
      "ball_certificate_id={}\ntarget_certificate_id={}\nprevious_unit_json_sha256={}\n",
      record.unit_json_sha256, CanonicalLimits(in.limits),
      in.budget.ball_radius_U_mm ? fmt::format("{}", *in.budget.ball_radius_U_mm) : std::string("default"),
      so.operator_name, so.station, so.ball_certificate_id, so.target_certificate_id,
      in.previous ? in.previous->unit_json_sha256 : std::string("none"));
}

std::string ReportId(const UnitRecord& record, const ReportInputs& inputs) {
  return record.serial + "-" + util::Sha256Hex(ReportIdText(record, inputs)).substr(0, kReportIdHexDigits);
}

std::string RenderHtmlReport(const UnitRecord& rec, const ReportInputs& inputs) {
  inputs.Validate(rec);
  const Limits& limits = inputs.limits;
  const std::string id = ReportId(rec, inputs);
  const Verdict verdict = Evaluate(rec, limits, inputs.budget);
  const char* verdict_word = verdict.pass ? "PASS" : "FAIL";
  int failed = 0;
  for (const Check& c : verdict.checks) failed += c.pass ? 0 : 1;

  std::string s;
  s += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  s += fmt::format("<meta name=\"report-id\" content=\"{}\">\n", H(id));
  s += fmt::format("<title>topocal QA report {} \u2014 {}</title>\n", H(id), verdict_word);
  s += fmt::format("<style>{}</style>\n</head>\n", kCss);
  s += fmt::format("<body data-report-id=\"{}\" data-verdict=\"{}\">\n", H(id), verdict_word);
  // Repeated on every printed page (position: fixed in @media print); the page-frame table's header and footer
  // rows keep the content clear of them.
  s += fmt::format("<div class=\"print-header\">topocal QA report <span class=\"report-id\">{}</span> \u00b7 unit {} "
                   "\u00b7 {}</div>\n",
                   H(id), H(rec.serial), verdict_word);
  s += fmt::format("<div class=\"print-footer\">Report <span class=\"report-id\">{}</span> \u00b7 record created {} "
                   "\u00b7 topocal {}</div>\n",
                   H(id), H(rec.created_utc), H(kVersion));
  s += "<table class=\"page-frame\"><thead><tr><td><div class=\"header-space\"></div></td></tr></thead>\n"
       "<tfoot><tr><td><div class=\"footer-space\"></div></td></tr></tfoot>\n<tbody><tr><td>\n<main>\n";

  // Title and verdict.
  s += fmt::format("<h1>Calibration QA report \u2014 unit {}</h1>\n", H(rec.serial));
  s += fmt::format("<p>Report id <strong class=\"report-id\" id=\"report-id\">{}</strong> \u00b7 record created {} "
                   "\u00b7 topocal {}</p>\n",
                   H(id), H(rec.created_utc), H(rec.tool_version));
  s += fmt::format("<div id=\"verdict\" class=\"banner {}\" data-verdict=\"{}\">{}<small>{} of {} checks passed "
                   "against {} ({} acceptance)</small></div>\n",
                   verdict.pass ? "pass" : "fail", verdict_word, verdict_word, verdict.checks.size() - failed,
                   verdict.checks.size(), H(limits.origin), ToString(limits.rule));
  if (!verdict.pass) {  // which checks failed, on the first page
    s += "<ul id=\"failed-checks\" class=\"failed\">\n";
    for (const std::string& f : FailedChecks(verdict)) s += fmt::format("<li>FAILED: {}</li>\n", H(f));
    s += "</ul>\n";
  }

  // Identity.
  s += "<section id=\"identity\" class=\"keep\"><h2>Device identity</h2>\n<table class=\"data\">\n";
  auto row = [&](const std::string& k, const std::string& v) {
    s += fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", k, v);
  };
  row("Serial", H(rec.serial));
  row("Report id", "<span class=\"report-id\">" + H(id) + "</span>");
  row("Record created (UTC)", H(rec.created_utc));
  row("Calibration date", H(rec.calibration.date.empty() ? "not in calibration.yaml" : rec.calibration.date));
  row("Tool version", "topocal " + H(rec.tool_version) +
                          (rec.tool_commit.empty() ? std::string() : " (commit " + H(rec.tool_commit) + ")"));
  row("Record", H(rec.directory));
  row("Record digests", "Appendix A (every file verified against its SHA-256 when this report was made)");
  row("Camera", fmt::format("{} \u00d7 {} px, pixel pitch {} \u00b5m, a = {} mm", rec.camera_width_px,
                            rec.camera_height_px, Sig(rec.camera_pixel_pitch_um), Sig(rec.camera_a_mm)));
  s += "</table></section>\n";

  // Sign-off: who measured, where, against which certified artefacts; lines to sign by hand.
  const SignOff& so = inputs.sign_off;
  const auto given = [](const std::string& v) {
    return v.empty() ? std::string("<span class=\"undefined\">not given</span>") : H(v);
  };
  s += "<section id=\"sign-off\" class=\"keep signoff\"><h2>Sign-off</h2>\n<table class=\"data\">\n";
  s += fmt::format("<tr><th>Operator</th><td data-field=\"operator\">{}</td><th>Station</th><td "
                   "data-field=\"station\">{}</td></tr>\n",
                   given(so.operator_name), given(so.station));
  s += fmt::format("<tr><th>Reference ball certificate</th><td data-field=\"ball-certificate\">{}</td><th>Ball radius "
                   "U (k = 2)</th><td>{}</td></tr>\n",
                   given(so.ball_certificate_id),
                   inputs.budget.ball_radius_U_mm
                       ? Sig(*inputs.budget.ball_radius_U_mm, 3) + " mm (certificate)"
                       : Sig(kDefaultBallRadiusUMm, 3) + " mm <span class=\"undefined\">(default: not given)</span>");
  s += fmt::format("<tr><th>Calibration target certificate</th><td data-field=\"target-certificate\" "
                   "colspan=\"3\">{}</td></tr>\n",
                   given(so.target_certificate_id));
  s += fmt::format("<tr><th>Verdict</th><td colspan=\"3\"><strong>{}</strong> (report <span class=\"report-id\">{}"
                   "</span>)</td></tr>\n",
                   verdict_word, H(id));
  s += "<tr><th>Signature</th><td class=\"blank\"></td><th>Date</th><td class=\"blank\"></td></tr>\n";
  s += "</table></section>\n";

  // Method.
  s += "<section id=\"method\" class=\"keep\"><h2>Method</h2>\n<table class=\"data\">\n";
  row("Distortion model", H(rec.settings_model) +
                              (rec.settings_model == "seidel"
                                   ? " (paper Eq. 18: k<sub>1</sub> alone, \u03c3 = k<sub>1</sub> M<sub>T</sub><sup>3</sup> "
                                     "/ f<sup>2</sup>)"
                                   : " (OpenCV Brown\u2013Conrady k<sub>1</sub>, k<sub>2</sub>, p<sub>1</sub>, "
                                     "p<sub>2</sub>, k<sub>3</sub>)"));
  row("Views", rec.settings_single_view
                   ? "single view of a planar target at the cornea position; f<sub>x</sub> = f<sub>y</sub> from focal "
                     "length and pixel pitch and the principal point at the image centre held fixed"
                   : fmt::format("multi-view ({} views), all intrinsics fitted", rec.views.size()));
  row("Distortion centre", rec.settings_fit_centre ? "fitted" : "at the principal point (fixed)");
  row("Reference sphere", rec.settings_sphere_radius_mm ? Fixed(*rec.settings_sphere_radius_mm, 4) + " mm"
                                                         : "none given");
  row("Uncertainty", rec.settings_uncertainty_samples > 0
                         ? fmt::format("calibration covariance carried to the clinical numbers by Monte Carlo, {} "
                                       "draws, seed {}; U = 2 s (k = 2)",
                                       rec.settings_uncertainty_samples, rec.settings_seed)
                         : std::string("not propagated (uncertainty samples = 0)"));
  row("Decision rule", H(DecisionRuleText(limits.rule)));
  s += "</table></section>\n";

  // Calibration.
  s += "<section id=\"calibration\" class=\"page-break\"><h2>Calibration</h2>\n";
  s += fmt::format("<p>Model {}, {} \u00d7 {} px, RMS reprojection error {} px over {} corners, {} outliers "
                   "rejected.</p>\n",
                   H(rec.calibration_model), rec.calibration_width_px, rec.calibration_height_px,
                   Sig(rec.calibration_rms_px, 4), rec.corners_used, rec.outliers);
  s += "<table class=\"data\"><tr><th>parameter</th><th>value</th><th>U (k = 2)</th><th></th></tr>\n";
  for (const CalibrationParameter& p : rec.parameters) {
    s += fmt::format("<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td>{}</td></tr>\n", H(p.name),
                     Sig(p.value, 7), p.fixed ? "\u2014" : "\u00b1 " + Sig(2 * p.stddev, 3),
                     p.fixed ? "fixed" : "fitted");
  }
  s += "</table>\n";
  if (rec.seidel_sigma_per_mm2) {
    s += fmt::format("<p id=\"seidel-sigma\">Seidel \u03c3 = <strong>{} \u00b1 {} mm<sup>\u22122</sup></strong> "
                     "(U, k = 2; M<sub>T</sub> = {}, f = {} mm; the focal length taken as exact).</p>\n",
                     Sig(*rec.seidel_sigma_per_mm2, 6), Sig(2 * rec.seidel_sigma_stddev_per_mm2.value_or(0), 3),
                     Sig(rec.seidel_magnification.value_or(0), 4), Sig(rec.seidel_focal_mm.value_or(0), 5));
  } else {
    s += "<p id=\"seidel-sigma\" class=\"note\">No Seidel \u03c3 in the record (not the Seidel model, or the focal "
         "length in mm unknown).</p>\n";
  }
  s += "</section>\n";

  // Residual plots.
  s += "<section id=\"residuals\"><h2>Residuals and distortion</h2>\n";
  std::vector<Bar> bars;
  for (std::size_t i = 0; i < rec.views.size(); ++i) {
    const std::string& image = rec.views[i].image;
    const std::string base = image.substr(image.find_last_of('/') + 1);
    bars.push_back({fmt::format("{} ({})", i + 1, base.empty() ? "view" : base), rec.views[i].rms_px});
  }
  s += SvgBarChart(bars, {"RMS reprojection error per view", "RMS (px)", limits.calibration_rms_px.max,
                          fmt::format("limit {} px", Sig(limits.calibration_rms_px.max, 3))});
  std::vector<Arrow> arrows;
  int outliers = 0;
  for (const CornerResidualRow& r : rec.residuals) {
    arrows.push_back({r.x_px, r.y_px, r.dx_px, r.dy_px, r.outlier});
    outliers += r.outlier ? 1 : 0;
  }
  QuiverOptions qo;
  qo.image_width_px = rec.calibration_width_px;
  qo.image_height_px = rec.calibration_height_px;
  qo.region = ResidualRegion(rec);
  qo.title = fmt::format("Residual vectors (predicted \u2212 observed), {} corners{}", rec.residuals.size(),
                         outliers ? fmt::format(", {} outliers in red", outliers) : std::string());
  s += SvgQuiver(arrows, qo);
  const PixelRegion field_region = FieldRegion(rec, qo.region);
  const bool whole_image = !rec.field_radius_px && !qo.region;
  const DistortionPlot field = DistortionField(rec.calibration.camera, field_region, whole_image, rec.field_radius_px);
  s += field.svg;
  s += fmt::format("<p class=\"note\">Distortion field from {} (the exact model, with its distortion centre) over {}: "
                   "largest displacement {} px.</p>\n",
                   H(rec.calibration_path),
                   rec.field_radius_px
                       ? fmt::format("the measurement field (the disc of radius {} px about the principal point, "
                                     "from unit.json; the plot's corners lie outside it)",
                                     Sig(*rec.field_radius_px, 4))
                       : (whole_image ? std::string("the whole image") : std::string("the region of the corners")),
                   Sig(field.max_displacement_px, 4));
  s += "</section>\n";

  // Reference sphere.
  s += "<section id=\"sphere\" class=\"page-break\"><h2>Reference sphere: before and after correction</h2>\n";
  if (rec.verification) {
    const SphereVerification& v = *rec.verification;
    s += fmt::format("<p>Image {}; true radius {} mm, true power {} D (n<sub>k</sub> = {}).</p>\n", H(v.image),
                     Fixed(v.radius_true_mm, 4), Fixed(v.power_true_D, 3), Sig(v.keratometric_index, 5));
    s += "<table class=\"data\"><tr><th>quantity</th><th>truth</th><th>uncorrected</th><th>corrected</th>"
         "<th>corrected, Monte Carlo mean \u00b1 U (k = 2)</th></tr>\n";
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

  // Paper cornea.
  s += "<section id=\"paper\" class=\"page-break\"><h2>Paper biconic cornea (simulated through this camera): before "
       "and after correction</h2>\n";
  s += "<table class=\"data\"><tr><th>quantity</th><th>truth</th><th>uncorrected</th><th>corrected</th>"
       "<th>corrected \u2212 truth</th><th>Monte Carlo mean \u00b1 U (k = 2)</th></tr>\n";
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

  if (rec.device) s += DeviceSection(rec);
  if (inputs.previous) s += PreviousComparison(rec, *inputs.previous, inputs);

  // Acceptance.
  s += "<section id=\"acceptance\" class=\"page-break\"><h2>Acceptance</h2>\n";
  s += fmt::format("<p><strong>Decision rule.</strong> {}</p>\n", H(DecisionRuleText(limits.rule)));
  s += "<table class=\"data\" id=\"checks\"><tr><th>check</th><th>|error|</th><th>U (k = 2)</th><th>limit</th>"
       "<th>result</th><th>note</th></tr>\n";
  for (const Check& c : verdict.checks) {
    const std::string unit = c.unit.empty() ? "" : " " + c.unit;
    s += fmt::format("<tr data-check=\"{}\"><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
                     "<td class=\"num\">{}</td><td class=\"{}\">{}</td><td class=\"note\">{}</td></tr>\n",
                     H(c.id), H(c.what), c.error ? Sig(*c.error, 4) + unit : "\u2014",
                     c.U ? Sig(*c.U, 3) + unit : "\u2014", Sig(c.limit, 4) + unit, c.pass ? "pass" : "fail",
                     c.pass ? "PASS" : "FAIL", H(c.note));
  }
  s += "</table>\n";
  // The simulated paper cornea, informative: what this calibration does to a typical eye, not evidence of it.
  s += "<h3>Informative, not a check: the paper cornea through this calibration</h3>\n<p class=\"note\">Simulated "
       "through the unit's own fitted calibration and corrected by the same calibration: its error shows what the "
       "calibration does to a typical eye, not whether the calibration is right (a broken unit shows the same "
       "numbers), so it is not part of the verdict.</p>\n";
  s += "<table class=\"data\" id=\"informative\"><tr><th>quantity</th><th>|error|</th><th>U (k = 2)</th>"
       "<th>informative threshold</th><th></th></tr>\n";
  for (const Check& c : PaperCorneaRows(rec, limits)) {
    const std::string unit = c.unit.empty() ? "" : " " + c.unit;
    s += fmt::format("<tr data-informative=\"{}\"><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>"
                     "<td class=\"num\">{}</td><td>{}</td></tr>\n",
                     H(c.id), H(c.what), c.error ? Sig(*c.error, 4) + unit : "\u2014",
                     c.U ? Sig(*c.U, 3) + unit : "\u2014", Sig(c.limit, 4) + unit,
                     c.pass ? "within" : "beyond");
  }
  s += "</table>\n";
  s += BudgetTables(verdict);
  s += fmt::format("<h3>Limits ({})</h3>\n<table class=\"data\"><tr><th>limit</th><th>value</th><th>source</th>"
                   "</tr>\n",
                   H(limits.origin));
  for (const NamedLimit& l : NamedLimits(limits)) {
    s += fmt::format("<tr><td>{}</td><td class=\"num\">{}{}{}</td><td class=\"note\">{}</td></tr>\n", l.name,
                     Sig(l.limit->max, 4), *l.unit ? " " : "", l.unit, H(l.limit->source));
  }
  s += "</table>\n";
  s += fmt::format("<p class=\"verdict-line\">Overall: <strong>{}</strong> (report <span class=\"report-id\">{}</span>)"
                   "</p>\n",
                   verdict_word, H(id));
  s += "</section>\n";

  // Inputs and record files.
  s += "<section id=\"inputs\" class=\"page-break\"><h2>Appendix A: provenance</h2>\n";
  s += fmt::format("<p>unit.json SHA-256 <span class=\"hash\">{}</span>; the report id hashes it with the limits, "
                   "the decision rule, the certificate's U and the sign-off (docs/report.md).</p>\n",
                   H(rec.unit_json_sha256));
  if (inputs.previous) {
    s += fmt::format("<p>Previous record {}: unit.json SHA-256 <span class=\"hash\">{}</span>.</p>\n",
                     H(inputs.previous->directory), H(inputs.previous->unit_json_sha256));
  }
  s += "<h3>Inputs</h3>\n<table class=\"data\"><tr><th>role</th><th>path</th>"
       "<th>SHA-256</th></tr>\n";
  for (const InputFile& f : rec.inputs) {
    s += fmt::format("<tr><td>{}</td><td>{}</td><td class=\"hash\">{}</td></tr>\n", H(f.role), H(f.path),
                     H(f.sha256));
  }
  s += "</table>\n<h3>Record files (each verified against its SHA-256 when this report was made)</h3>\n"
       "<table class=\"data\"><tr><th>file</th><th>SHA-256</th></tr>\n";
  for (const RecordFile& f : rec.files) {
    s += fmt::format("<tr><td>{}</td><td class=\"hash\">{}</td></tr>\n", H(f.name), H(f.sha256));
  }
  s += "</table></section>\n";

  s += "</main>\n</td></tr></tbody></table>\n";
  s += fmt::format("<script>{}</script>\n", kImageCheckScript);
  s += "</body>\n</html>\n";
  return s;
}

nlohmann::json ReportJson(const UnitRecord& rec, const ReportInputs& inputs) {
  using nlohmann::json;
  inputs.Validate(rec);
  const Limits& l = inputs.limits;
  const Verdict verdict = Evaluate(rec, l, inputs.budget);
  json checks = json::array();
  for (const Check& c : verdict.checks) {
    json budget = json::array();
    for (const BudgetTerm& t : c.budget) budget.push_back({{"input", t.name}, {"source", t.source}, {"u", t.u}});
    json j = {{"id", c.id},
              {"what", c.what},
              {"unit", c.unit},
              {"value", c.error ? json(*c.error) : json(nullptr)},
              {"U", c.U ? json(*c.U) : json(nullptr)},
              {"coverage_factor", 2},
              {"budget", budget},
              {"limit", c.limit},
              {"verdict", c.pass ? "PASS" : "FAIL"},
              {"note", c.note}};
    if (!c.budget.empty()) j["combined_standard_uncertainty"] = CombinedStandardUncertainty(c.budget);
    checks.push_back(j);
  }
  json informative = json::array();  // the paper cornea: not part of the verdict
  for (const Check& c : PaperCorneaRows(rec, l)) {
    informative.push_back({{"id", c.id},
                           {"what", c.what},
                           {"unit", c.unit},
                           {"value", c.error ? json(*c.error) : json(nullptr)},
                           {"U", c.U ? json(*c.U) : json(nullptr)},
                           {"coverage_factor", 2},
                           {"threshold", c.limit},
                           {"within", c.pass}});
  }
  json limits = json::object();
  for (const NamedLimit& named : NamedLimits(l)) {
    limits[named.name] = {{"max", named.limit->max}, {"source", named.limit->source}};
  }
  const SignOff& so = inputs.sign_off;
  json out = {{"format", kReportJsonFormat},
              {"format_version", kReportJsonFormatVersion},
              {"tool_version", kVersion},
              {"report_id", ReportId(rec, inputs)},
              {"serial", rec.serial},
              {"record", rec.directory},
              {"unit_json_sha256", rec.unit_json_sha256},
              {"record_created_utc", rec.created_utc},
              {"decision_rule", ToString(l.rule)},
              {"decision_rule_text", DecisionRuleText(l.rule)},
              {"limits_origin", l.origin},
              {"limits", limits},
              {"ball_radius_U_mm", inputs.budget.ball_radius_U_mm.value_or(kDefaultBallRadiusUMm)},
              {"ball_radius_U_is_default", !inputs.budget.ball_radius_U_mm.has_value()},
              {"sign_off",
               {{"operator", so.operator_name},
                {"station", so.station},
                {"ball_certificate_id", so.ball_certificate_id},
                {"target_certificate_id", so.target_certificate_id}}},
              {"checks", checks},
              {"informative", informative},
              {"checks_passed", std::count_if(verdict.checks.begin(), verdict.checks.end(),
                                              [](const Check& c) { return c.pass; })},
              {"verdict", verdict.pass ? "PASS" : "FAIL"}};
  if (inputs.previous) {
    const Verdict vp = Evaluate(*inputs.previous, l, inputs.budget);
    json comparison = json::array();
    for (const ComparisonRow& r : ComparisonRows(rec, *inputs.previous, inputs)) {
      const auto number = [](const std::optional<double>& v) { return v ? json(*v) : json(nullptr); };
      const auto change = r.Change();
      const auto U = r.ChangeU();
      comparison.push_back({{"id", r.id},
                            {"unit", r.plain_unit},
                            {"previous", number(r.prev)},
                            {"now", number(r.now)},
                            {"change", number(change)},
                            {"U_change", number(U)},
                            {"coverage_factor", 2},
                            {"within_U", change && U ? json(std::abs(*change) <= *U) : json(nullptr)}});
    }
    out["previous"] = {{"record", inputs.previous->directory},
                       {"unit_json_sha256", inputs.previous->unit_json_sha256},
                       {"record_created_utc", inputs.previous->created_utc},
                       {"verdict", vp.pass ? "PASS" : "FAIL"},
                       {"comparison", comparison}};
  }
  return out;
}

}  // namespace topocal::report
