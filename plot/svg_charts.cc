#include "plot/svg_charts.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>

#include "plot/svg.h"
#include "util/io.h"

namespace topocal::plot {
namespace {

// Drawing sizes in SVG user units (the SVG scales to the page width; text keeps its proportion).
constexpr double kPlotWidth = 640;
constexpr double kMarginLeft = 56, kMarginRight = 16, kMarginTop = 30, kMarginBottom = 44;
constexpr double kColourBarWidth = 14, kColourBarGap = 12, kColourBarLabelRoom = 64;
// The longest vector is drawn about this fraction of the larger image side.
constexpr double kLongestArrowFraction = 0.06;
constexpr double kArrowHeadFraction = 0.3;   // head length / arrow length
constexpr double kArrowHeadMaxUnits = 6;     // head length cap, user units
constexpr const char* kArrowColour = "#1f4e9e";
constexpr const char* kHighlightColour = "#c62828";
constexpr const char* kNoDataColour = "#dcdcdc";  // background cells without data
constexpr const char* kFont = "font-family=\"DejaVu Sans, Arial, sans-serif\"";

std::string Num(double v, int decimals = 2) {
  if (!std::isfinite(v)) return "0";
  return fmt::format("{:.{}f}", v, decimals);
}

// Shortest readable label of a value (3 significant digits).
std::string Label(double v) {
  if (!std::isfinite(v)) return "n/a";
  if (v == 0) return "0";
  // Whole numbers up to a million as integers ("x1000", not "x1e+03").
  if (std::abs(v) >= 1 && std::abs(v) < 1e6 && v == std::round(v)) return fmt::format("{:.0f}", v);
  return fmt::format("{:.3g}", v);
}

// A blue-to-yellow ramp (viridis anchors), t in [0, 1].
std::string Colour(double t) {
  static constexpr std::array<std::array<double, 3>, 5> kStops = {{{68, 1, 84}, {59, 82, 139}, {33, 145, 140},
                                                                   {94, 201, 98}, {253, 231, 37}}};
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * (kStops.size() - 1);
  const int i = std::min(static_cast<int>(t), static_cast<int>(kStops.size()) - 2);
  const double f = t - i;
  std::array<int, 3> c{};
  for (int k = 0; k < 3; ++k) c[k] = static_cast<int>(std::lround(kStops[i][k] + f * (kStops[i + 1][k] - kStops[i][k])));
  return fmt::format("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
}

}  // namespace

double NiceFloor(double x) {
  if (!std::isfinite(x) || x <= 0) return 1;
  const double decade = std::pow(10.0, std::floor(std::log10(x)));
  const double m = x / decade;
  // 1e-9 relative slack so that an exact 2 x 10^n is not floored to 1 x 10^n by rounding in log10/pow.
  if (m >= 5 * (1 - 1e-9)) return 5 * decade;
  if (m >= 2 * (1 - 1e-9)) return 2 * decade;
  return decade;
}

std::string SvgBarChart(const std::vector<Bar>& bars, const BarChartOptions& o) {
  double top = o.limit.value_or(0);
  for (const Bar& b : bars) {
    if (!std::isfinite(b.value) || b.value < 0) throw util::InputError("bar chart: values must be finite and >= 0");
    top = std::max(top, b.value);
  }
  if (top <= 0) top = 1;
  const double tick = NiceFloor(top / 4);
  const double axis_max = std::ceil(top * 1.1 / tick) * tick;
  const double plot_h = 200;
  const double w = kPlotWidth, h = kMarginTop + plot_h + kMarginBottom + 20;
  const double inner_w = w - kMarginLeft - kMarginRight;
  auto y_of = [&](double v) { return kMarginTop + plot_h * (1 - v / axis_max); };

  std::string s = fmt::format(
      "<svg class=\"plot\" viewBox=\"0 0 {} {}\" role=\"img\" "
      "aria-label=\"{}\">\n",
      Num(w, 0), Num(h, 0), EscapeXml(o.title));
  s += fmt::format("<text x=\"{}\" y=\"18\" font-size=\"13\" font-weight=\"bold\" {}>{}</text>\n", Num(kMarginLeft),
                   kFont, EscapeXml(o.title));
  for (double v = 0; v <= axis_max * (1 + 1e-9); v += tick) {
    s += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{}\" y2=\"{}\" stroke=\"#ddd\"/>\n", Num(kMarginLeft),
                     Num(w - kMarginRight), Num(y_of(v)), Num(y_of(v)));
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" text-anchor=\"end\" {}>{}</text>\n",
                     Num(kMarginLeft - 4), Num(y_of(v) + 3), kFont, Label(v));
  }
  s += fmt::format(
      "<text transform=\"translate(12 {}) rotate(-90)\" font-size=\"11\" text-anchor=\"middle\" {}>{}</text>\n",
      Num(kMarginTop + plot_h / 2), kFont, EscapeXml(o.value_label));
  const double slot = bars.empty() ? inner_w : inner_w / bars.size();
  const double bar_w = std::min(slot * 0.6, 80.0);
  for (std::size_t i = 0; i < bars.size(); ++i) {
    const double cx = kMarginLeft + slot * (i + 0.5);
    const double y = y_of(bars[i].value);
    s += fmt::format("<rect class=\"bar\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>\n",
                     Num(cx - bar_w / 2), Num(y), Num(bar_w), Num(kMarginTop + plot_h - y), kArrowColour);
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" text-anchor=\"middle\" {}>{}</text>\n", Num(cx),
                     Num(y - 4), kFont, Label(bars[i].value));
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" text-anchor=\"middle\" {}>{}</text>\n", Num(cx),
                     Num(kMarginTop + plot_h + 14), kFont, EscapeXml(bars[i].label));
  }
  if (o.limit) {
    s += fmt::format(
        "<line x1=\"{}\" x2=\"{}\" y1=\"{}\" y2=\"{}\" stroke=\"{}\" stroke-dasharray=\"6 4\" stroke-width=\"1.5\"/>\n",
        Num(kMarginLeft), Num(w - kMarginRight), Num(y_of(*o.limit)), Num(y_of(*o.limit)), kHighlightColour);
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" text-anchor=\"end\" fill=\"{}\" {}>{}</text>\n",
                     Num(w - kMarginRight), Num(y_of(*o.limit) - 4), kHighlightColour, kFont,
                     EscapeXml(o.limit_label));
  }
  s += fmt::format("<line x1=\"{0}\" x2=\"{0}\" y1=\"{1}\" y2=\"{2}\" stroke=\"#333\"/>\n", Num(kMarginLeft),
                   Num(kMarginTop), Num(kMarginTop + plot_h));
  s += fmt::format("<line x1=\"{0}\" x2=\"{1}\" y1=\"{2}\" y2=\"{2}\" stroke=\"#333\"/>\n", Num(kMarginLeft),
                   Num(w - kMarginRight), Num(kMarginTop + plot_h));
  s += "</svg>\n";
  return s;
}

namespace {

// The quiver's geometry: the image region drawn, the vectors' magnification and the plot area in user units.
struct QuiverFrame {
  PixelRegion region;
  double longest, magnification;
  bool bar;  // a background field with its colour bar
  double inner_w, scale, x0, y0, inner_h, w, h;
  double X(double x_px) const { return x0 + (x_px - region.x_px) * scale; }
  double Y(double y_px) const { return y0 + (y_px - region.y_px) * scale; }
};

QuiverFrame FrameQuiver(const std::vector<Arrow>& arrows, const QuiverOptions& o) {
  if (o.image_width_px <= 0 || o.image_height_px <= 0) throw util::InputError("quiver: image size must be > 0");
  double longest = 0;
  for (const Arrow& a : arrows) {
    if (!std::isfinite(a.x_px) || !std::isfinite(a.y_px) || !std::isfinite(a.dx_px) || !std::isfinite(a.dy_px)) {
      throw util::InputError("quiver: non-finite arrow");
    }
    longest = std::max(longest, std::hypot(a.dx_px, a.dy_px));
  }
  const PixelRegion region = o.region.value_or(PixelRegion{-0.5, -0.5, static_cast<double>(o.image_width_px),
                                                            static_cast<double>(o.image_height_px)});
  if (!(region.width_px > 0) || !(region.height_px > 0)) throw util::InputError("quiver: empty region");
  const double img_w = region.width_px, img_h = region.height_px;
  const double magnification =
      o.magnification.value_or(longest > 0 ? NiceFloor(kLongestArrowFraction * std::max(img_w, img_h) / longest) : 1);
  // Pixel x covers [x - 0.5, x + 0.5]: the region's left edge is at region.x_px.
  const bool bar = o.background.has_value();
  const double right = kMarginRight + (bar ? kColourBarGap + kColourBarWidth + kColourBarLabelRoom : 0);
  const double inner_w = kPlotWidth - 20 - right;
  const double scale = inner_w / img_w;  // user units per pixel
  const double x0 = 20, y0 = kMarginTop;
  const double inner_h = img_h * scale;
  const double w = kPlotWidth, h = y0 + inner_h + kMarginBottom;
  return QuiverFrame{region, longest, magnification, bar, inner_w, scale, x0, y0, inner_h, w, h};
}

// The background's colour range: its values' extent unless the field sets it.
std::pair<double, double> BackgroundRange(const CellField& f) {
  if (f.cols <= 0 || f.rows <= 0 || f.values.size() != static_cast<std::size_t>(f.cols) * f.rows) {
    throw util::InputError("quiver: background grid size does not match its values");
  }
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : f.values) {
    if (std::isinf(v)) throw util::InputError("quiver: infinite background value");
    if (std::isnan(v)) continue;  // no data
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (!std::isfinite(lo)) lo = 0, hi = 1;  // no cell with data
  lo = f.value_min.value_or(lo);
  hi = f.value_max.value_or(hi);
  if (!std::isfinite(lo) || !std::isfinite(hi)) throw util::InputError("quiver: non-finite colour range");
  return {lo, hi};
}

std::string ColourBar(const QuiverFrame& q, double lo, double hi, const std::string& label) {
  std::string s;
  const double bx = q.x0 + q.inner_w + kColourBarGap;
  constexpr int kBarSteps = 32;
  for (int i = 0; i < kBarSteps; ++i) {
    const double t = 1.0 - (i + 0.5) / kBarSteps;
    s += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>", Num(bx),
                     Num(q.y0 + i * q.inner_h / kBarSteps), Num(kColourBarWidth), Num(q.inner_h / kBarSteps + 0.3),
                     Colour(t));
  }
  s += "\n";
  s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" {}>{}</text>\n", Num(bx + kColourBarWidth + 4),
                   Num(q.y0 + 8), kFont, Label(hi));
  s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" {}>{}</text>\n", Num(bx + kColourBarWidth + 4),
                   Num(q.y0 + q.inner_h), kFont, Label(lo));
  s += fmt::format(
      "<text transform=\"translate({} {}) rotate(90)\" font-size=\"10\" text-anchor=\"middle\" {}>{}</text>\n",
      Num(bx + kColourBarWidth + 30), Num(q.y0 + q.inner_h / 2), kFont, EscapeXml(label));
  return s;
}

// The background field as cells under the plot, and its colour bar.
std::string QuiverBackground(const CellField& f, const QuiverFrame& q) {
  const auto [lo, hi] = BackgroundRange(f);
  const double span = hi > lo ? hi - lo : 1;
  const double cw = q.inner_w / f.cols, ch = q.inner_h / f.rows;
  std::string s;
  s += "<g class=\"field\" shape-rendering=\"crispEdges\">\n";
  for (int r = 0; r < f.rows; ++r) {
    for (int c = 0; c < f.cols; ++c) {
      // Cells overlap by a hair so no background seam shows between them.
      const double v = f.values[r * f.cols + c];
      s += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\"/>", Num(q.x0 + c * cw),
                       Num(q.y0 + r * ch), Num(cw + 0.3), Num(ch + 0.3),
                       std::isnan(v) ? std::string(kNoDataColour) : Colour((v - lo) / span));
    }
    s += "\n";
  }
  s += "</g>\n";
  s += ColourBar(q, lo, hi, f.label);
  return s;
}

std::string QuiverArrows(const std::vector<Arrow>& arrows, const QuiverFrame& q) {
  std::string s;
  s += "<g class=\"arrows\" stroke-linecap=\"round\">\n";
  for (const Arrow& a : arrows) {
    const double bx = q.X(a.x_px), by = q.Y(a.y_px);
    const double ex = bx + a.dx_px * q.magnification * q.scale, ey = by + a.dy_px * q.magnification * q.scale;
    const double len = std::hypot(ex - bx, ey - by);
    const char* colour = a.highlight ? kHighlightColour : kArrowColour;
    s += fmt::format("<line x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"{}\" stroke-width=\"0.8\"/>", Num(bx),
                     Num(by), Num(ex), Num(ey), colour);
    if (len > 1e-6) {
      const double head = std::min(kArrowHeadFraction * len, kArrowHeadMaxUnits);
      const double ux = (ex - bx) / len, uy = (ey - by) / len;
      const double hx = ex - head * ux, hy = ey - head * uy;
      s += fmt::format("<polygon points=\"{},{} {},{} {},{}\" fill=\"{}\"/>", Num(ex), Num(ey),
                       Num(hx - 0.4 * head * uy), Num(hy + 0.4 * head * ux), Num(hx + 0.4 * head * uy),
                       Num(hy - 0.4 * head * ux), colour);
    }
    s += "\n";
  }
  s += "</g>\n";
  return s;
}

// Scale bar: a round displacement about half the longest, drawn at the plot's magnification; then what part of
// the image is shown.
std::string QuiverCaption(const QuiverOptions& o, const QuiverFrame& q) {
  std::string s;
  const double bar_value = q.longest > 0 ? NiceFloor(q.longest / 2) : 1;
  const double bar_len = bar_value * q.magnification * q.scale;
  const double sy = q.y0 + q.inner_h + 22;
  s += fmt::format("<line class=\"scale-bar\" x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"#000\" "
                   "stroke-width=\"2\"/>\n",
                   Num(q.x0), Num(sy), Num(q.x0 + bar_len), Num(sy));
  s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" {}>{} {} (vectors magnified \u00d7{}; longest {} {})"
                   "</text>\n",
                   Num(q.x0 + bar_len + 8), Num(sy + 4), kFont, Label(bar_value), EscapeXml(o.caption_unit),
                   Label(q.magnification), Label(q.longest), EscapeXml(o.caption_unit));
  const PixelRegion& region = q.region;
  if (o.region) {
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" fill=\"#555\" {}>x {} to {} px, y {} to {} px of the "
                     "{} \u00d7 {} px image</text>\n",
                     Num(q.x0), Num(sy + 18), kFont, Label(std::round(region.x_px)),
                     Label(std::round(region.x_px + region.width_px)), Label(std::round(region.y_px)),
                     Label(std::round(region.y_px + region.height_px)), o.image_width_px, o.image_height_px);
  } else {
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" fill=\"#555\" {}>image {} \u00d7 {} px</text>\n",
                     Num(q.x0), Num(sy + 18), kFont, o.image_width_px, o.image_height_px);
  }
  return s;
}

}  // namespace

std::string SvgQuiver(const std::vector<Arrow>& arrows, const QuiverOptions& o) {
  const QuiverFrame q = FrameQuiver(arrows, o);
  std::string s = fmt::format(
      "<svg class=\"plot\" viewBox=\"0 0 {} {}\" role=\"img\" "
      "aria-label=\"{}\">\n",
      Num(q.w, 0), Num(q.h, 0), EscapeXml(o.title));
  s += fmt::format("<text x=\"{}\" y=\"18\" font-size=\"13\" font-weight=\"bold\" {}>{}</text>\n", Num(q.x0), kFont,
                   EscapeXml(o.title));
  if (q.bar) s += QuiverBackground(*o.background, q);
  s += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#333\"/>\n", Num(q.x0),
                   Num(q.y0), Num(q.inner_w), Num(q.inner_h));
  s += QuiverArrows(arrows, q);
  s += QuiverCaption(o, q);
  s += "</svg>\n";
  return s;
}

namespace {

struct Range {
  double lo = 0, hi = 1;
  double Y(double v, double top, double h) const { return top + h * (1 - (v - lo) / (hi - lo)); }
};

// Nice ticks covering [lo, hi]: at most kMaxTicks, counted rather than stepped (a step below the values' rounding —
// identical values a few ulps apart, or 1e308 beside ordinary ones — would never advance). A range whose nice step
// is not finite, not positive or below the rounding of its ends gets its two ends as ticks.
std::vector<double> AxisTicks(double lo, double hi) {
  constexpr int kMaxTicks = 12;
  const double step = NiceFloor((hi - lo) / 4);
  const double start = std::ceil(lo / step - 1e-9) * step;
  if (!std::isfinite(step) || !(step > 0) || !std::isfinite(start) || start + step == start ||
      !(hi >= lo) || !std::isfinite(hi - lo)) {
    return std::isfinite(lo) && std::isfinite(hi) ? std::vector<double>{lo, hi} : std::vector<double>{};
  }
  std::vector<double> t;
  for (int i = 0; i < kMaxTicks; ++i) {
    const double v = start + i * step;
    if (v > hi + 1e-9 * step) break;
    t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  }
  return t;
}

// Widens [lo, hi] by 5 % each side; a zero-width range becomes +-1 (or +-10 % of the value).
Range Padded(double lo, double hi) {
  if (!(hi > lo)) {
    const double d = lo == 0 ? 1.0 : 0.1 * std::abs(lo);
    return {lo - d, hi + d};
  }
  const double pad = 0.05 * (hi - lo);
  return {lo - pad, hi + pad};
}

// The control chart's value scale: the values, the control limits and (when not far off) the acceptance limit.
struct ChartScale {
  Range r;
  bool two_sided, limit_on_scale;
};

ChartScale ControlScale(const ControlChartPlot& p) {
  double lo = 0, hi = 0;
  bool first = true;
  for (double v : p.values) {
    if (!std::isfinite(v)) continue;
    lo = first ? v : std::min(lo, v);
    hi = first ? v : std::max(hi, v);
    first = false;
  }
  if (p.centre && p.sigma) {
    lo = std::min(lo, *p.centre - 3 * *p.sigma);
    hi = std::max(hi, *p.centre + 3 * *p.sigma);
  }
  // A signed quantity (errors) is judged on |value| <= limit: both lines; a positive one (RMS) only +limit.
  const bool two_sided = lo < 0;
  bool limit_on_scale = false;
  if (p.limit) {
    const double span = std::max(hi - lo, 1e-12);
    limit_on_scale = *p.limit <= std::max(std::abs(hi), std::abs(lo)) + 2 * span;
    if (limit_on_scale) {
      hi = std::max(hi, *p.limit);
      if (two_sided) lo = std::min(lo, -*p.limit);
    }
  }
  return {Padded(lo, hi), two_sided, limit_on_scale};
}

// The control chart's drawing: margins, size and plot area in user units.
struct ChartArea {
  double left = 62, right = 40, top = 24, bottom = 30;
  double w, h, pw, ph;
  explicit ChartArea(const ControlChartPlot& p)
      : w(p.width), h(p.height), pw(w - left - right), ph(h - top - bottom) {}
};

// The value grid, the value axis's label and the plot's frame.
std::string ChartAxes(const ControlChartPlot& p, const ChartArea& a, const Range& r) {
  std::string s;
  for (double v : AxisTicks(r.lo, r.hi)) {
    const double y = r.Y(v, a.top, a.ph);
    s += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{}\" y2=\"{}\" stroke=\"#eee\"/>\n", Num(a.left),
                     Num(a.w - a.right), Num(y), Num(y));
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"9\" text-anchor=\"end\" {}>{}</text>\n", Num(a.left - 4),
                     Num(y + 3), kFont, Label(v));
  }
  s += fmt::format("<text transform=\"translate(11 {}) rotate(-90)\" font-size=\"10\" text-anchor=\"middle\" {}>{}"
                   "</text>\n",
                   Num(a.top + a.ph / 2), kFont, EscapeXml(p.value_label));
  s += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#999\"/>\n", Num(a.left),
                   Num(a.top), Num(a.pw), Num(a.ph));
  return s;
}

// A horizontal line at value v; a labelled one is a reference ("ref"), an unlabelled one a zone boundary.
std::string HLine(const ChartArea& a, const Range& r, double v, const char* colour, const char* dash,
                  const std::string& label) {
  std::string s;
  const double y = r.Y(v, a.top, a.ph);
  s += fmt::format("<line class=\"{}\" x1=\"{}\" x2=\"{}\" y1=\"{}\" y2=\"{}\" stroke=\"{}\"{}/>\n",
                   label.empty() ? "zone" : "ref", Num(a.left), Num(a.w - a.right), Num(y), Num(y), colour,
                   *dash ? fmt::format(" stroke-dasharray=\"{}\"", dash) : std::string());
  if (!label.empty()) {
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"9\" {} fill=\"{}\">{}</text>\n", Num(a.w - a.right + 2),
                     Num(y + 3), kFont, colour, EscapeXml(label));
  }
  return s;
}

// The 1 and 2 sigma zones, the control limits and the centre line; the acceptance limit where it is on scale.
std::string ControlLines(const ControlChartPlot& p, const ChartArea& a, const ChartScale& sc) {
  std::string s;
  const Range& r = sc.r;
  if (p.centre && p.sigma) {
    for (int k : {1, 2}) {
      s += HLine(a, r, *p.centre + k * *p.sigma, "#bbb", "2 3", "");
      s += HLine(a, r, *p.centre - k * *p.sigma, "#bbb", "2 3", "");
    }
    s += HLine(a, r, *p.centre + 3 * *p.sigma, "#c62828", "", "UCL");
    s += HLine(a, r, *p.centre - 3 * *p.sigma, "#c62828", "", "LCL");
    s += HLine(a, r, *p.centre, "#2e7d32", "", "CL");
  }
  if (p.limit && sc.limit_on_scale) {
    s += HLine(a, r, *p.limit, "#000", "6 3", "+lim");
    if (sc.two_sided) s += HLine(a, r, -*p.limit, "#000", "6 3", "\u2212lim");
  }
  return s;
}

// The values as a line through points, the flagged ones larger and in the warning colour.
std::string ControlSeries(const ControlChartPlot& p, const ChartArea& a, const Range& r) {
  std::string s;
  const int n = static_cast<int>(p.values.size());
  const auto x_of = [&](int i) { return a.left + (n <= 1 ? a.pw / 2 : a.pw * i / (n - 1)); };
  std::string path;
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(p.values[i])) continue;
    path += fmt::format("{}{} {} ", path.empty() ? "M" : "L", Num(x_of(i)), Num(r.Y(p.values[i], a.top, a.ph)));
  }
  if (!path.empty()) s += fmt::format("<path d=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"0.8\"/>\n", path, kArrowColour);
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(p.values[i])) continue;
    const bool flag = i < static_cast<int>(p.flagged.size()) && p.flagged[i];
    s += fmt::format("<circle class=\"{}\" cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{}\"/>\n", flag ? "point flagged" : "point",
                     Num(x_of(i)), Num(r.Y(p.values[i], a.top, a.ph)), flag ? "3" : "2",
                     flag ? kHighlightColour : kArrowColour);
  }
  return s;
}

// The first and last unit's labels and the x axis's caption.
std::string ControlXAxis(const ControlChartPlot& p, const ChartArea& a, const ChartScale& sc) {
  std::string s;
  const int n = static_cast<int>(p.values.size());
  if (p.x_labels.size() >= 2) {
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"9\" {}>{}</text>\n", Num(a.left), Num(a.h - 8), kFont,
                     EscapeXml(p.x_labels.front()));
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"9\" text-anchor=\"end\" {}>{}</text>\n", Num(a.w - a.right),
                     Num(a.h - 8), kFont, EscapeXml(p.x_labels.back()));
  }
  s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"9\" text-anchor=\"middle\" {}>{}, in order of calibration "
                   "({}){}</text>\n",
                   Num(a.left + a.pw / 2), Num(a.h - 8), kFont,
                   p.subgroup_size > 1 ? fmt::format("mean of {} consecutive units", p.subgroup_size) : "unit", n,
                   p.limit && !sc.limit_on_scale ? fmt::format("; acceptance limit \u00b1{} off scale", Label(*p.limit))
                                                 : std::string());
  return s;
}

}  // namespace

std::string SvgControlChart(const ControlChartPlot& p) {
  const ChartArea a(p);
  const ChartScale sc = ControlScale(p);
  std::string s = fmt::format("<svg class=\"plot chart\" viewBox=\"0 0 {} {}\" role=\"img\" aria-label=\"{}\">\n",
                              Num(a.w, 0), Num(a.h, 0), EscapeXml(p.title));
  s += fmt::format("<text x=\"{}\" y=\"15\" font-size=\"12\" font-weight=\"bold\" {}>{}</text>\n", Num(a.left), kFont,
                   EscapeXml(p.title));
  s += ChartAxes(p, a, sc.r);
  s += ControlLines(p, a, sc);
  s += ControlSeries(p, a, sc.r);
  s += ControlXAxis(p, a, sc);
  s += "</svg>\n";
  return s;
}

int HistogramBinCount(std::size_t n) {
  return std::clamp(static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n)))), 5, kMaxHistogramBins);
}

HistogramBins BinValues(const std::vector<double>& values) {
  HistogramBins h;
  std::vector<double> v;
  for (double x : values) {
    if (std::isfinite(x)) v.push_back(x);
  }
  if (v.empty()) return h;
  const auto [mn, mx] = std::minmax_element(v.begin(), v.end());
  h.lo = *mn;
  h.hi = *mx;
  h.n = static_cast<std::int64_t>(v.size());
  const int bins = HistogramBinCount(v.size());
  const double bw = (h.hi - h.lo) / bins;
  h.counts.assign(bins, 0);
  for (double x : v) h.counts[bw > 0 ? std::min(bins - 1, static_cast<int>((x - h.lo) / bw)) : bins / 2]++;
  return h;
}

std::string SvgHistogram(const HistogramPlot& p) {
  const double left = 40, right = 12, top = 24, bottom = 34;
  const double w = p.width, h = p.height, pw = w - left - right, ph = h - top - bottom;
  const HistogramBins hist = p.bins ? *p.bins : BinValues(p.values);
  std::string s = fmt::format("<svg class=\"plot histogram\" viewBox=\"0 0 {} {}\" role=\"img\" aria-label=\"{}\">\n",
                              Num(w, 0), Num(h, 0), EscapeXml(p.title));
  s += fmt::format("<text x=\"{}\" y=\"15\" font-size=\"12\" font-weight=\"bold\" {}>{}</text>\n", Num(left), kFont,
                   EscapeXml(p.title));
  if (hist.n == 0 || hist.counts.empty()) return s + "</svg>\n";
  double lo = hist.lo, hi = hist.hi;
  if (p.limit && *p.limit <= 2 * std::max(std::abs(lo), std::abs(hi))) {
    hi = std::max(hi, *p.limit);
    if (lo < 0) lo = std::min(lo, -*p.limit);
  }
  const Range r = Padded(lo, hi);
  const int bins = static_cast<int>(hist.counts.size());
  const double bw = (hist.hi - hist.lo) / bins;
  const std::vector<std::int64_t>& count = hist.counts;
  const std::int64_t cmax = *std::max_element(count.begin(), count.end());
  const auto x_of = [&](double x) { return left + pw * (x - r.lo) / (r.hi - r.lo); };
  for (int b = 0; b < bins; ++b) {
    const double x0 = bw > 0 ? hist.lo + b * bw : hist.lo - 0.5 * (r.hi - r.lo) / bins + (b - bins / 2) * (r.hi - r.lo) / bins;
    const double x1 = bw > 0 ? x0 + bw : x0 + (r.hi - r.lo) / bins;
    const double bh = ph * static_cast<double>(count[b]) / static_cast<double>(std::max<std::int64_t>(1, cmax));
    s += fmt::format("<rect class=\"bin\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"{}\" stroke=\"#fff\" "
                     "stroke-width=\"0.5\"/>\n",
                     Num(x_of(x0)), Num(top + ph - bh), Num(std::max(0.5, x_of(x1) - x_of(x0))), Num(bh), kArrowColour);
  }
  s += fmt::format("<line x1=\"{}\" x2=\"{}\" y1=\"{}\" y2=\"{}\" stroke=\"#999\"/>\n", Num(left), Num(w - right),
                   Num(top + ph), Num(top + ph));
  s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"9\" text-anchor=\"end\" {}>{}</text>\n", Num(left - 3),
                   Num(top + 8), kFont, cmax);
  for (double t : AxisTicks(r.lo, r.hi)) {
    s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"9\" text-anchor=\"middle\" {}>{}</text>\n", Num(x_of(t)),
                     Num(top + ph + 12), kFont, Label(t));
  }
  if (p.limit) {
    for (double l : {*p.limit, -*p.limit}) {
      if (l < r.lo || l > r.hi) continue;
      s += fmt::format("<line class=\"ref\" x1=\"{0}\" x2=\"{0}\" y1=\"{1}\" y2=\"{2}\" stroke=\"#000\" "
                       "stroke-dasharray=\"6 3\"/>\n",
                       Num(x_of(l)), Num(top), Num(top + ph));
    }
  }
  s += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"10\" text-anchor=\"middle\" {}>{} (n = {})</text>\n",
                   Num(left + pw / 2), Num(h - 6), kFont, EscapeXml(p.value_label), hist.n);
  s += "</svg>\n";
  return s;
}

}  // namespace topocal::plot
