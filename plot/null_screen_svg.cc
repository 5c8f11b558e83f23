#include "plot/null_screen_svg.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <fmt/format.h>

#include "plot/svg.h"

namespace topocal::plot {

namespace {

// Sheet (mm, y up, sector rotated so that its bisector points up) to SVG user units (mm, y down).
class SheetToSvg {
 public:
  SheetToSvg(double rotation_rad, double min_x, double max_y) : rot_(rotation_rad), min_x_(min_x), max_y_(max_y) {}
  Eigen::Vector2d Rotate(const Eigen::Vector2d& q) const {
    return {std::cos(rot_) * q.x() - std::sin(rot_) * q.y(), std::sin(rot_) * q.x() + std::cos(rot_) * q.y()};
  }
  // A point given in the unrotated development (polar (s, psi) as in ConeDevelopment).
  Eigen::Vector2d Svg(const Eigen::Vector2d& sheet) const {
    const Eigen::Vector2d r = Rotate(sheet);
    return {r.x() - min_x_, max_y_ - r.y()};
  }
  Eigen::Vector2d Polar(double s, double psi) const { return Svg({s * std::cos(psi), s * std::sin(psi)}); }
  // The SVG rotation (degrees, clockwise positive) of text running along the direction psi, turned by 180 deg
  // where needed so that it never reads upside down.
  double TextAngleDeg(double psi) const {
    double deg = std::remainder(-(psi + rot_) * 180.0 / M_PI, 360.0);
    if (deg > 90.0) deg -= 180.0;
    if (deg < -90.0) deg += 180.0;
    return deg;
  }

 private:
  double rot_, min_x_, max_y_;
};

std::string P(const Eigen::Vector2d& p) { return fmt::format("{:.3f},{:.3f}", p.x(), p.y()); }

std::string OutlinePath(const SheetToSvg& t, const std::vector<Eigen::Vector2d>& pts, double rotate_psi) {
  const double c = std::cos(rotate_psi), s = std::sin(rotate_psi);
  std::string d;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector2d q(c * pts[i].x() - s * pts[i].y(), s * pts[i].x() + c * pts[i].y());
    d += i == 0 ? 'M' : 'L';
    d += P(t.Svg(q));
  }
  return d + "Z";
}

constexpr double kTickMm = 2.0, kTickLabelMm = 5.5, kFontMm = 3.0, kSmallFontMm = 2.4;
constexpr double kSideMarginMm = 12.0, kTopMarginMm = 30.0, kBottomMarginMm = 24.0;

// The development as placed on the page: the sector (angle theta, slants s_in..s_out) and the page's size.
struct Sheet {
  const model::ConeDevelopment& dev;
  double theta, s_in, s_out;
  SheetToSvg t;
  double width_mm, height_mm;
  std::string large;  // the rims' SVG large-arc flag
};

Sheet PlaceOnPage(const model::NullScreenLayout& layout, const NullScreenSvgOptions& options) {
  const auto& dev = layout.development;
  const double theta = dev.SectorAngleRad();
  const double s_in = layout.inner_slant_mm, s_out = layout.outer_slant_mm;
  const double rot = 0.5 * M_PI - 0.5 * theta;  // bisector of the sector points up on the page

  // Bounding box of everything drawn around the sector, in the rotated sheet frame.
  const SheetToSvg probe(rot, 0.0, 0.0);
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x, min_y = min_x, max_y = -min_x;
  const auto extend = [&](const Eigen::Vector2d& sheet) {
    const Eigen::Vector2d r = probe.Rotate(sheet);
    min_x = std::min(min_x, r.x());
    max_x = std::max(max_x, r.x());
    min_y = std::min(min_y, r.y());
    max_y = std::max(max_y, r.y());
  };
  const double tab_psi = theta + (options.glue_tab_mm + 1.0) / std::max(s_in, 1.0);
  for (int k = 0; k <= 200; ++k) {
    const double psi = -0.05 + (tab_psi + 0.1) * k / 200.0;
    for (double s : {s_in, s_out + kTickLabelMm + kFontMm}) extend({s * std::cos(psi), s * std::sin(psi)});
  }
  const SheetToSvg t(rot, min_x - kSideMarginMm, max_y + kTopMarginMm);
  const double width_mm = (max_x - min_x) + 2 * kSideMarginMm;
  const double height_mm = (max_y - min_y) + kTopMarginMm + kBottomMarginMm;
  return Sheet{dev, theta, s_in, s_out, t, width_mm, height_mm, theta > M_PI ? "1" : "0"};
}

}  // namespace

Eigen::Vector2d NullScreenPageSizeMm(const model::NullScreenLayout& layout, const NullScreenSvgOptions& options) {
  const Sheet sh = PlaceOnPage(layout, options);
  return {sh.width_mm, sh.height_mm};
}

namespace {

std::string SvgOpening(const Sheet& sh, const std::string& title) {
  std::string svg;
  svg += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  svg += fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"{0:.3f}mm\" height=\"{1:.3f}mm\" "
      "viewBox=\"0 0 {0:.3f} {1:.3f}\">\n",
      sh.width_mm, sh.height_mm);
  svg += fmt::format("<title>{}</title>\n", EscapeXml(title));
  svg += "<rect x=\"0\" y=\"0\" width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n";
  return svg;
}

// The sector: cut edge psi = 0, outer rim, second edge psi = theta, inner rim.
std::string SectorPath(const Sheet& sh) {
  const SheetToSvg& t = sh.t;
  const double s_in = sh.s_in, s_out = sh.s_out, theta = sh.theta;
  return fmt::format("M{}L{}A{:.3f},{:.3f} 0 {} 0 {}L{}A{:.3f},{:.3f} 0 {} 1 {}Z", P(t.Polar(s_in, 0)),
                     P(t.Polar(s_out, 0)), s_out, s_out, sh.large, P(t.Polar(s_out, theta)), P(t.Polar(s_in, theta)),
                     s_in, s_in, sh.large, P(t.Polar(s_in, 0)));
}

// Glue tab beyond the second edge: it goes under the cut edge when the sheet is rolled into the cone.
std::string GlueTab(const Sheet& sh, double glue_tab_mm) {
  const SheetToSvg& t = sh.t;
  const double s_in = sh.s_in, s_out = sh.s_out, theta = sh.theta;
  std::string svg;
  const Eigen::Vector2d a(s_in * std::cos(theta), s_in * std::sin(theta));
  const Eigen::Vector2d b(s_out * std::cos(theta), s_out * std::sin(theta));
  const Eigen::Vector2d e = (b - a).normalized(), n(-e.y(), e.x());
  const double w = glue_tab_mm, chamfer = std::min(w, 0.25 * (s_out - s_in));
  const Eigen::Vector2d b2 = b + w * n - chamfer * e, a2 = a + w * n + chamfer * e;
  svg += fmt::format(
      "<path d=\"M{}L{}L{}L{}\" fill=\"none\" stroke=\"#c00000\" stroke-width=\"0.25\"/>\n",
      P(t.Svg(a)), P(t.Svg(a2)), P(t.Svg(b2)), P(t.Svg(b)));
  const Eigen::Vector2d mid = t.Svg(0.5 * (a + b) + 0.5 * w * n);
  svg += fmt::format(
      "<text x=\"{:.3f}\" y=\"{:.3f}\" font-family=\"sans-serif\" font-size=\"{}\" text-anchor=\"middle\" "
      "dominant-baseline=\"middle\" transform=\"rotate({:.3f} {:.3f} {:.3f})\">glue tab (under the cut edge)</text>\n",
      mid.x(), mid.y(), kSmallFontMm, t.TextAngleDeg(theta), mid.x(), mid.y());
  return svg;
}

// Spot outlines. An outline cut by the seam is drawn again one sector angle away; the clip keeps the halves.
std::string SpotOutlines(const Sheet& sh, const model::NullScreenLayout& layout, const char* spot_fill) {
  std::string svg;
  svg += fmt::format("<g id=\"spots\" fill=\"{}\" stroke=\"none\" clip-path=\"url(#sector)\">\n", spot_fill);
  for (const auto& o : layout.outlines) {
    svg += fmt::format("<path id=\"spot-{}-{}\" d=\"{}\"/>\n", o.id.ring, o.id.index, OutlinePath(sh.t, o.sheet_mm, 0.0));
  }
  for (const auto& o : layout.outlines) {
    if (!o.crosses_seam) continue;
    const double psi_t = std::atan2(o.target_sheet_mm.y(), o.target_sheet_mm.x());
    const double shift = psi_t < 0.5 * sh.theta ? sh.theta : -sh.theta;
    svg += fmt::format("<path id=\"spot-{}-{}-seam\" d=\"{}\"/>\n", o.id.ring, o.id.index,
                       OutlinePath(sh.t, o.sheet_mm, shift));
  }
  svg += "</g>\n";
  return svg;
}

// Cut lines: the cut edge and both rims solid; the fold between the sector and the glue tab dashed.
std::string CutLines(const Sheet& sh) {
  const SheetToSvg& t = sh.t;
  const double s_in = sh.s_in, s_out = sh.s_out, theta = sh.theta;
  std::string svg;
  svg += "<g fill=\"none\" stroke=\"#c00000\" stroke-width=\"0.25\">\n";
  svg += fmt::format("<path id=\"cut-line\" d=\"M{}L{}\"/>\n", P(t.Polar(s_in, 0)), P(t.Polar(s_out, 0)));
  svg += fmt::format("<path id=\"outer-rim\" d=\"M{}A{:.3f},{:.3f} 0 {} 0 {}\"/>\n", P(t.Polar(s_out, 0)), s_out,
                     s_out, sh.large, P(t.Polar(s_out, theta)));
  svg += fmt::format("<path id=\"inner-rim\" d=\"M{}A{:.3f},{:.3f} 0 {} 0 {}\"/>\n", P(t.Polar(s_in, 0)), s_in, s_in,
                     sh.large, P(t.Polar(s_in, theta)));
  svg += fmt::format("<path id=\"fold-line\" d=\"M{}L{}\" stroke-dasharray=\"1.5,1\"/>\n", P(t.Polar(s_in, theta)),
                     P(t.Polar(s_out, theta)));
  svg += "</g>\n";
  return svg;
}

std::string TextAlong(const SheetToSvg& t, double s, double psi, double offset_mm, const std::string& text,
                      double size_mm) {
  // Text parallel to the generator at psi, moved offset_mm sideways (positive: towards larger psi).
  const Eigen::Vector2d dir(std::cos(psi), std::sin(psi)), side(-dir.y(), dir.x());
  const Eigen::Vector2d p = t.Svg(s * dir + offset_mm * side);
  return fmt::format(
      "<text x=\"{0:.3f}\" y=\"{1:.3f}\" font-family=\"sans-serif\" font-size=\"{2}\" text-anchor=\"middle\" "
      "dominant-baseline=\"middle\" transform=\"rotate({3:.3f} {0:.3f} {1:.3f})\">{4}</text>\n",
      p.x(), p.y(), size_mm, t.TextAngleDeg(psi), EscapeXml(text));
}

// Azimuth ticks every 30 deg of the cone's azimuth (from +x towards +y), to align the cone with the camera.
std::string AzimuthTicks(const Sheet& sh) {
  const SheetToSvg& t = sh.t;
  std::string svg;
  svg += "<g stroke=\"#000000\" stroke-width=\"0.25\">\n";
  std::string labels;
  for (int deg = 0; deg < 360; deg += 30) {
    double dphi = std::fmod(deg * M_PI / 180.0 - sh.dev.cut_azimuth_rad, 2.0 * M_PI);
    if (dphi < 0) dphi += 2.0 * M_PI;
    const double psi = dphi * std::sin(sh.dev.semi_angle_rad);
    const Eigen::Vector2d dir(std::cos(psi), std::sin(psi));
    svg += fmt::format("<path d=\"M{}L{}\"/>\n", P(t.Svg(sh.s_out * dir)), P(t.Svg((sh.s_out + kTickMm) * dir)));
    const Eigen::Vector2d lp = t.Svg((sh.s_out + kTickLabelMm) * dir);
    labels += fmt::format(
        "<text x=\"{:.3f}\" y=\"{:.3f}\" font-family=\"sans-serif\" font-size=\"{}\" text-anchor=\"middle\" "
        "dominant-baseline=\"middle\">{}</text>\n",
        lp.x(), lp.y(), kSmallFontMm, deg == 0 ? "0\u00b0 (+x)" : deg == 90 ? "90\u00b0 (+y)" : fmt::format("{}\u00b0", deg));
  }
  svg += "</g>\n" + labels;
  return svg;
}

// Rim names, outside the sector near the middle of each arc.
std::string RimNames(const Sheet& sh) {
  const double s_in = sh.s_in, s_out = sh.s_out, theta = sh.theta;
  std::string svg;
  const Eigen::Vector2d o = sh.t.Polar(s_out + kTickLabelMm + 4.5, 0.5 * theta);
  svg += fmt::format(
      "<text x=\"{:.3f}\" y=\"{:.3f}\" font-family=\"sans-serif\" font-size=\"{}\" text-anchor=\"middle\">"
      "outer rim: eye end (slant {:.1f} mm from the cone apex)</text>\n",
      o.x(), o.y(), kSmallFontMm, s_out);
  // Below the lowest points of the inner rim (its ends), on the bisector.
  const Eigen::Vector2d i = sh.t.Polar(std::max(s_in * std::cos(0.5 * theta) - 4.0, 0.0), 0.5 * theta);
  svg += fmt::format(
      "<text x=\"{:.3f}\" y=\"{:.3f}\" font-family=\"sans-serif\" font-size=\"{}\" text-anchor=\"middle\">"
      "inner rim: camera end (slant {:.1f} mm)</text>\n",
      i.x(), i.y(), kSmallFontMm, s_in);
  return svg;
}

// Title and instructions at the top.
std::string Instructions(const Sheet& sh, const std::string& title) {
  std::string svg;
  svg += fmt::format(
      "<text x=\"{:.3f}\" y=\"8\" font-family=\"sans-serif\" font-size=\"{}\" font-weight=\"bold\">{}</text>\n",
      kSideMarginMm, kFontMm + 1.0, EscapeXml(title));
  svg += fmt::format(
      "<text x=\"{:.3f}\" y=\"13\" font-family=\"sans-serif\" font-size=\"{}\">Cone semi-angle {:.3f} deg, apex at "
      "z = {:.2f} mm; development: sector of {:.3f} deg, 1:1.</text>\n",
      kSideMarginMm, kSmallFontMm, sh.dev.semi_angle_rad * 180.0 / M_PI, sh.dev.apex_z_mm, sh.theta * 180.0 / M_PI);
  svg += fmt::format(
      "<text x=\"{:.3f}\" y=\"17\" font-family=\"sans-serif\" font-size=\"{}\">Print at 100 % (no fit to page) "
      "and check the scale bar with a ruler. Cut along the red solid lines,</text>\n",
      kSideMarginMm, kSmallFontMm);
  svg += fmt::format(
      "<text x=\"{:.3f}\" y=\"21\" font-family=\"sans-serif\" font-size=\"{}\">fold the tab on the dashed line, "
      "roll with the printed face inside and glue the tab under the cut edge.</text>\n",
      kSideMarginMm, kSmallFontMm);
  return svg;
}

// Scale bar, bottom left.
std::string ScaleBar(const Sheet& sh, double scale_bar_mm) {
  const double x0 = kSideMarginMm, y0 = sh.height_mm - 12.0, len = scale_bar_mm;
  return fmt::format(
      "<g id=\"scale-bar\"><rect x=\"{:.3f}\" y=\"{:.3f}\" width=\"{:.3f}\" height=\"1\" fill=\"#000000\"/>"
      "<path d=\"M{:.3f},{:.3f}V{:.3f}M{:.3f},{:.3f}V{:.3f}\" stroke=\"#000000\" stroke-width=\"0.2\"/>"
      "<text x=\"{:.3f}\" y=\"{:.3f}\" font-family=\"sans-serif\" font-size=\"{}\" text-anchor=\"middle\">"
      "{:g} mm</text></g>\n",
      x0, y0, len, x0, y0 - 1.5, y0 + 2.5, x0 + len, y0 - 1.5, y0 + 2.5, x0 + 0.5 * len, y0 + 6.0, kFontMm, len);
}

}  // namespace

std::string NullScreenSvg(const model::NullScreenLayout& layout, const NullScreenSvgOptions& options) {
  const Sheet sh = PlaceOnPage(layout, options);
  const char* sector_fill = options.bright_spots ? "#000000" : "#ffffff";
  const char* spot_fill = options.bright_spots ? "#ffffff" : "#000000";

  const std::string title = fmt::format("topocal null screen: {}, {} spots", options.title, layout.outlines.size());
  std::string svg = SvgOpening(sh, title);
  const std::string sector = SectorPath(sh);
  svg += fmt::format("<defs><clipPath id=\"sector\"><path d=\"{}\"/></clipPath></defs>\n", sector);
  svg += GlueTab(sh, options.glue_tab_mm);
  svg += fmt::format("<path d=\"{}\" fill=\"{}\" stroke=\"none\"/>\n", sector, sector_fill);
  svg += SpotOutlines(sh, layout, spot_fill);
  svg += CutLines(sh);

  const double cut_deg = sh.dev.cut_azimuth_rad * 180.0 / M_PI;
  svg += TextAlong(sh.t, 0.5 * (sh.s_in + sh.s_out), 0.0, -3.0,
                   fmt::format("CUT: seam on the generator at azimuth {:.2f} deg", cut_deg), kSmallFontMm);
  svg += AzimuthTicks(sh);
  svg += RimNames(sh);
  svg += Instructions(sh, title);
  svg += ScaleBar(sh, options.scale_bar_mm);
  svg += "</svg>\n";
  return svg;
}

}  // namespace topocal::plot
