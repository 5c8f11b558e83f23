#include "plot/scatter_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_set>

#include <fmt/format.h>

#include "plot/svg.h"

namespace topocal::plot {
namespace {

constexpr double kWidth = 760, kHeight = 500;
constexpr double kLeft = 86, kRight = 190, kTop = 44, kBottom = 78;
// A log axis spans at most this many decades; anything smaller is drawn on the axis (hollow), not lost.
constexpr double kMaxDecades = 8;

struct Axis {
  bool log = true;
  double lo = 0, hi = 1;  // data units
  double pixel_lo = 0, pixel_hi = 1;

  double T(double v) const { return log ? std::log10(v) : v; }
  bool Clamped(double v) const { return (log && !(v > 0)) || v < lo; }
  double Pixel(double v) const {
    const double c = Clamped(v) ? lo : std::min(v, hi);
    return pixel_lo + (T(c) - T(lo)) / (T(hi) - T(lo)) * (pixel_hi - pixel_lo);
  }
};

Axis MakeAxis(bool log, const std::vector<double>& values, double pixel_lo, double pixel_hi) {
  Axis a;
  a.log = log;
  a.pixel_lo = pixel_lo;
  a.pixel_hi = pixel_hi;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const double v : values) {
    if (!std::isfinite(v) || (log && !(v > 0))) continue;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (!std::isfinite(lo)) {
    lo = log ? 1e-3 : 0.0;
    hi = 1.0;
  }
  if (log) {
    double dlo = std::floor(std::log10(lo)), dhi = std::ceil(std::log10(hi));
    if (dhi <= dlo) dhi = dlo + 1;
    dlo = std::max(dlo, dhi - kMaxDecades);
    a.lo = std::pow(10.0, dlo);
    a.hi = std::pow(10.0, dhi);
  } else {
    const double pad = hi > lo ? 0.05 * (hi - lo) : 1.0;
    a.lo = lo - pad;
    a.hi = hi + pad;
  }
  return a;
}

std::vector<double> Ticks(const Axis& a) {
  std::vector<double> t;
  if (a.log) {
    for (double d = std::round(std::log10(a.lo)); d <= std::round(std::log10(a.hi)); d += 1) t.push_back(std::pow(10.0, d));
    return t;
  }
  const double step = std::pow(10.0, std::floor(std::log10((a.hi - a.lo) / 4)));
  for (double v = std::ceil(a.lo / step) * step; v <= a.hi; v += step) t.push_back(v);
  return t;
}

std::string TickLabel(const Axis& a, double v) {
  if (a.log) return fmt::format("1e{}", static_cast<int>(std::round(std::log10(v))));
  return fmt::format("{:g}", v);
}

// Grid, ticks and labels.
std::string GridAndAxes(const ScatterPlot& plot, const Axis& x, const Axis& y) {
  std::string svg;
  for (const double t : Ticks(x)) {
    const double px = x.Pixel(t);
    svg += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" stroke=\"#ddd\"/>\n", px,
                       kTop, kHeight - kBottom);
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">{}</text>\n", px,
                       kHeight - kBottom + 18, TickLabel(x, t));
  }
  for (const double t : Ticks(y)) {
    const double py = y.Pixel(t);
    svg += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{2:.1f}\" y2=\"{1:.1f}\" stroke=\"#ddd\"/>\n", kLeft,
                       py, kWidth - kRight);
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"end\">{}</text>\n", kLeft - 6, py + 4,
                       TickLabel(y, t));
  }
  svg += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" fill=\"none\" "
                     "stroke=\"black\"/>\n",
                     kLeft, kTop, kWidth - kLeft - kRight, kHeight - kTop - kBottom);
  svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">{}</text>\n", (kLeft + kWidth - kRight) / 2,
                     kHeight - kBottom + 40, EscapeXml(plot.x_label));
  svg += fmt::format("<text transform=\"translate(22 {:.1f}) rotate(-90)\" text-anchor=\"middle\">{}</text>\n",
                     (kTop + kHeight - kBottom) / 2, EscapeXml(plot.y_label));
  return svg;
}

// The points of each series that get a marker: all of them, or (beyond plot.max_markers) the first of each series
// in each occupied cell of `*cell_px` px (hollow and filled markers apart), the cell doubled from the marker's radius
// until they fit. *cell_px is 0 when every point is drawn.
std::vector<std::vector<size_t>> MarkedPoints(const ScatterPlot& plot, const Axis& x, const Axis& y, double* cell_px) {
  std::vector<std::vector<size_t>> marked(plot.series.size());
  size_t total = 0;
  for (const auto& s : plot.series) total += s.points.size();
  *cell_px = 0;
  if (plot.max_markers == 0 || total <= plot.max_markers) {
    for (size_t k = 0; k < marked.size(); ++k) {
      for (size_t i = 0; i < plot.series[k].points.size(); ++i) marked[k].push_back(i);
    }
    return marked;
  }
  for (double cell = 3;; cell *= 2) {
    size_t drawn = 0;
    for (size_t k = 0; k < marked.size(); ++k) {
      marked[k].clear();
      std::unordered_set<std::uint64_t> occupied;
      const auto& points = plot.series[k].points;
      for (size_t i = 0; i < points.size(); ++i) {
        const bool clamped = x.Clamped(points[i].x) || y.Clamped(points[i].y);
        // Pixels lie within [0, kWidth] x [0, kHeight]: the cell indices fit 20 bits each.
        const auto cx = static_cast<std::uint64_t>(x.Pixel(points[i].x) / cell);
        const auto cy = static_cast<std::uint64_t>(y.Pixel(points[i].y) / cell);
        if (occupied.insert((cx << 21) | (cy << 1) | (clamped ? 1 : 0)).second) marked[k].push_back(i);
      }
      drawn += marked[k].size();
    }
    if (drawn <= plot.max_markers || cell > kWidth) {
      *cell_px = cell;
      return marked;
    }
  }
}

// Points, then the reference lines above them.
std::string PointsAndLines(const ScatterPlot& plot, const Axis& x, const Axis& y,
                           const std::vector<std::vector<size_t>>& marked) {
  std::string svg;
  for (size_t k = 0; k < plot.series.size(); ++k) {
    const auto& s = plot.series[k];
    svg += fmt::format("<g fill=\"{0}\" stroke=\"{0}\" fill-opacity=\"0.55\">\n", EscapeXml(s.colour));
    for (const size_t i : marked[k]) {
      const auto& p = s.points[i];
      const bool clamped = x.Clamped(p.x) || y.Clamped(p.y);
      svg += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"3\"{}/>\n", x.Pixel(p.x), y.Pixel(p.y),
                         clamped ? " fill=\"none\"" : "");
    }
    svg += "</g>\n";
  }
  for (const auto& l : plot.horizontal) {
    const double py = y.Pixel(l.value);
    svg += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{2:.1f}\" y2=\"{1:.1f}\" stroke=\"{3}\" "
                       "stroke-dasharray=\"6 4\" stroke-width=\"1.5\"/>\n",
                       kLeft, py, kWidth - kRight, EscapeXml(l.colour));
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" fill=\"{}\">{}</text>\n", kLeft + 4, py - 4, EscapeXml(l.colour),
                       EscapeXml(l.label));
  }
  for (const auto& l : plot.vertical) {
    const double px = x.Pixel(l.value);
    svg += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" stroke=\"{3}\" "
                       "stroke-dasharray=\"2 3\" stroke-width=\"1.5\"/>\n",
                       px, kTop, kHeight - kBottom, EscapeXml(l.colour));
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" fill=\"{}\">{}</text>\n", px + 4, kTop + 14, EscapeXml(l.colour),
                       EscapeXml(l.label));
  }
  return svg;
}

// Legend (with how the markers were thinned, when they were), and the note under the plot.
std::string LegendAndNote(const ScatterPlot& plot, const std::vector<std::vector<size_t>>& marked, double cell_px) {
  std::string svg;
  double ly = kTop + 10;
  for (const auto& s : plot.series) {
    svg += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"4\" fill=\"{}\"/>\n", kWidth - kRight + 18, ly,
                       EscapeXml(s.colour));
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\">{} ({})</text>\n", kWidth - kRight + 28, ly + 4,
                       EscapeXml(s.label), s.points.size());
    ly += 18;
  }
  if (cell_px > 0) {
    size_t drawn = 0;
    for (const auto& m : marked) drawn += m.size();
    const std::string lines[] = {fmt::format("{} markers for", drawn), "the points above:",
                                 fmt::format("one per {:g} px cell,", cell_px), "the first in it"};
    for (const auto& line : lines) {
      svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"11\" fill=\"#444\">{}</text>\n",
                         kWidth - kRight + 12, ly + 4, line);
      ly += 14;
    }
  }
  if (!plot.note.empty()) {
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"11\" fill=\"#444\">{}</text>\n", kLeft,
                       kHeight - 12, EscapeXml(plot.note));
  }
  return svg;
}

}  // namespace

std::string RenderScatterSvg(const ScatterPlot& plot) {
  std::vector<double> xs, ys;
  for (const auto& s : plot.series) {
    for (const auto& p : s.points) {
      xs.push_back(p.x);
      ys.push_back(p.y);
    }
  }
  for (const auto& l : plot.vertical) xs.push_back(l.value);
  for (const auto& l : plot.horizontal) ys.push_back(l.value);
  const Axis x = MakeAxis(plot.log_x, xs, kLeft, kWidth - kRight);
  const Axis y = MakeAxis(plot.log_y, ys, kHeight - kBottom, kTop);

  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{0}\" height=\"{1}\" fill=\"white\"/>\n",
      kWidth, kHeight);
  svg += fmt::format("<text x=\"{:.1f}\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">{}</text>\n",
                     (kLeft + kWidth - kRight) / 2, EscapeXml(plot.title));
  double cell_px = 0;
  const auto marked = MarkedPoints(plot, x, y, &cell_px);
  svg += GridAndAxes(plot, x, y);
  svg += PointsAndLines(plot, x, y, marked);
  svg += LegendAndNote(plot, marked, cell_px);
  svg += "</svg>\n";
  return svg;
}

}  // namespace topocal::plot
