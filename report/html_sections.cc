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

std::string H(std::string_view s) { return plot::EscapeXml(s); }

// Fixed decimals, never "nan", never "-0.000".
std::string Fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "\u2014";
  std::string s = fmt::format("{:.{}f}", v, decimals);
  if (s.front() == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);
  return s;
}

std::string Sig(double v, int digits) {
  if (!std::isfinite(v)) return "\u2014";
  if (v == 0) return "0";
  return fmt::format("{:.{}g}", v, digits);
}

namespace {

using plot::Arrow;
using plot::Bar;
using plot::CellField;
using plot::PixelRegion;
using plot::QuiverOptions;
using plot::SvgBarChart;
using plot::SvgQuiver;

// Grids of the distortion-field plot: coloured cells (magnitude) and arrows, over the whole image.
constexpr int kFieldCellsAcross = 48;

constexpr int kFieldArrowsAcross = 16;

// The residual plot zooms on the corners when they span less than this fraction of the image in both directions,
// with this relative margin around them.
constexpr double kZoomBelowFraction = 0.5;

constexpr double kZoomMargin = 0.15;

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
    model::CameraModel::NormalizedToPixel(cam.lens, in, cam.dist.data(), cam.distortion_centre.data(), u, px);
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

// The budget of each check whose U has more than one input: every contribution, its share of u_c^2, the total.
std::string BudgetTables(const Verdict& v) {
  std::string s;
  for (const Check& c : v.checks) {
    if (c.budget.size() < 2 || !c.U) continue;
    const double uc = CombinedStandardUncertainty(c.budget);
    const std::string unit = c.unit.empty() ? "" : " " + c.unit;
    s += fmt::format("<div class=\"keep\"><h3>Uncertainty budget: {}</h3>\n"
                     "<table class=\"data budget\" data-budget=\"{}\"><tr>"
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
                     "data-U=\"{}\">{}</td><td></td></tr>\n</table></div>\n",
                     H(c.id), Sig(*c.U, 3) + unit);
  }
  s += "<p class=\"note\">The paper-cornea checks are a simulation (truth exact, images noise-free): their U is the "
       "calibration's alone.</p>\n";
  return s;
}

// One row of a two-column table: a heading and its value (HTML).
std::string Row(const std::string& heading, const std::string& value) {
  return fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", heading, value);
}

}  // namespace

// Who the unit is: serial, report id, dates, tool, record and camera.
std::string IdentitySection(const UnitRecord& rec, const std::string& id) {
  std::string s;
  s += "<section id=\"identity\" class=\"keep\"><h2>Device identity</h2>\n<table class=\"data\">\n";
  s += Row("Serial", H(rec.serial));
  s += Row("Report id", "<span class=\"report-id\">" + H(id) + "</span>");
  s += Row("Record created (UTC)", H(rec.created_utc));
  s += Row("Calibration date", H(rec.calibration.date.empty() ? "not in calibration.yaml" : rec.calibration.date));
  s += Row("Tool version", "topocal " + H(rec.tool_version) +
                               (rec.tool_commit.empty() ? std::string() : " (commit " + H(rec.tool_commit) + ")"));
  s += Row("Record", H(rec.directory));
  s += Row("Record digests", "Appendix A (every file verified against its SHA-256 when this report was made)");
  s += Row("Camera", fmt::format("{} \u00d7 {} px, pixel pitch {} \u00b5m, a = {} mm", rec.camera_width_px,
                                 rec.camera_height_px, Sig(rec.camera_pixel_pitch_um), Sig(rec.camera_a_mm)));
  s += "</table></section>\n";
  return s;
}

// Sign-off: who measured, where, against which certified artefacts; lines to sign by hand.
std::string SignOffSection(const ReportInputs& inputs, const char* verdict_word, const std::string& id) {
  std::string s;
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
  return s;
}

// How the unit was calibrated and judged.
std::string UncertaintyText(const pipeline::UncertaintySetting& setting, int seed) {
  switch (setting.method) {
    case pipeline::UncertaintySetting::Method::kLinear:
      return "calibration covariance carried to the clinical numbers by linear propagation (central differences "
             "along its eigen-directions); U = 2 u (k = 2)";
    case pipeline::UncertaintySetting::Method::kMonteCarlo:
      return fmt::format("calibration covariance carried to the clinical numbers by Monte Carlo, {} draws, seed {}; "
                         "U = 2 s (k = 2)", setting.draws, seed);
    case pipeline::UncertaintySetting::Method::kNone: break;
  }
  return "not propagated (--uncertainty none)";
}

std::string MethodSection(const UnitRecord& rec, const Limits& limits) {
  std::string s;
  s += "<section id=\"method\" class=\"keep\"><h2>Method</h2>\n<table class=\"data\">\n";
  const char* model_text =
      rec.settings_model == "seidel"
          ? " (paper Eq. 18: k<sub>1</sub> alone, \u03c3 = k<sub>1</sub> M<sub>T</sub><sup>3</sup> / f<sup>2</sup>)"
          : " (OpenCV Brown\u2013Conrady k<sub>1</sub>, k<sub>2</sub>, p<sub>1</sub>, p<sub>2</sub>, k<sub>3</sub>)";
  s += Row("Distortion model", H(rec.settings_model) + model_text);
  s += Row("Views", rec.settings_single_view
                        ? "single view of a planar target at the cornea position; f<sub>x</sub> = f<sub>y</sub> from "
                          "focal length and pixel pitch and the principal point at the image centre held fixed"
                        : fmt::format("multi-view ({} views), all intrinsics fitted", rec.views.size()));
  s += Row("Distortion centre", rec.settings_fit_centre ? "fitted" : "at the principal point (fixed)");
  s += Row("Reference sphere", rec.settings_sphere_radius_mm ? Fixed(*rec.settings_sphere_radius_mm, 4) + " mm"
                                                              : "none given");
  s += Row("Uncertainty", UncertaintyText(rec.settings_uncertainty, rec.settings_seed));
  s += Row("Decision rule", H(DecisionRuleText(limits.rule)));
  s += "</table></section>\n";
  return s;
}

// The fitted camera: every parameter with its U.
std::string CalibrationSection(const UnitRecord& rec) {
  std::string s;
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
  return s;
}

// Reprojection residuals per view and over the image, and the distortion field.
std::string ResidualsSection(const UnitRecord& rec, const Limits& limits) {
  std::string s;
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
  return s;
}

// The checks of the verdict, the informative paper-cornea rows, the budgets and the limits.
std::string AcceptanceSection(const UnitRecord& rec, const Limits& limits, const Verdict& verdict,
                              const char* verdict_word, const std::string& id) {
  std::string s;
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
  s += "<div class=\"keep\"><h3>Informative, not a check: the paper cornea through this calibration</h3>\n"
       "<p class=\"note\">Simulated "
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
  s += "</table></div>\n";
  s += BudgetTables(verdict);
  s += fmt::format("<div class=\"keep\"><h3>Limits ({})</h3>\n<table class=\"data\"><tr><th>limit</th><th>value</th>"
                   "<th>source</th></tr>\n",
                   H(limits.origin));
  for (const NamedLimit& l : NamedLimits(limits)) {
    s += fmt::format("<tr><td>{}</td><td class=\"num\">{}{}{}</td><td class=\"note\">{}</td></tr>\n", l.name,
                     Sig(l.limit->max, 4), *l.unit ? " " : "", l.unit, H(l.limit->source));
  }
  s += "</table></div>\n";
  s += fmt::format("<p class=\"verdict-line\">Overall: <strong>{}</strong> (report <span class=\"report-id\">{}</span>)"
                   "</p>\n",
                   verdict_word, H(id));
  s += "</section>\n";
  return s;
}

// Appendix A: the digests of the inputs and of every record file.
std::string ProvenanceSection(const UnitRecord& rec, const ReportInputs& inputs) {
  std::string s;
  s += "<section id=\"inputs\" class=\"page-break\"><h2>Appendix A: provenance</h2>\n";
  s += fmt::format("<p>unit.json SHA-256 <span class=\"hash\">{}</span>; the report id hashes it with the limits, "
                   "the decision rule, the certificate's U and the sign-off (docs/report.md).</p>\n",
                   H(rec.unit_json_sha256));
  if (inputs.previous) {
    s += fmt::format("<p>Previous record {}: unit.json SHA-256 <span class=\"hash\">{}</span>.</p>\n",
                     H(inputs.previous->directory), H(inputs.previous->unit_json_sha256));
  }
  // Each table kept whole with its heading (.keep: break-inside avoid); one longer than a page runs on, its heading
  // kept with its first rows (h3: break-after avoid).
  s += "<div class=\"keep\"><h3>Inputs</h3>\n<table class=\"data\"><tr><th>role</th><th>path</th>"
       "<th>SHA-256</th></tr>\n";
  for (const InputFile& f : rec.inputs) {
    s += fmt::format("<tr><td>{}</td><td>{}</td><td class=\"hash\">{}</td></tr>\n", H(f.role), H(f.path),
                     H(f.sha256));
  }
  s += "</table></div>\n<div class=\"keep\"><h3>Record files (each verified against its SHA-256 when this report was "
       "made)</h3>\n<table class=\"data\"><tr><th>file</th><th>SHA-256</th></tr>\n";
  for (const RecordFile& f : rec.files) {
    s += fmt::format("<tr><td>{}</td><td class=\"hash\">{}</td></tr>\n", H(f.name), H(f.sha256));
  }
  s += "</table></div></section>\n";
  return s;
}

}  // namespace topocal::report::html
