#include "plot/map_image.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "plot/map_text.h"
#include "plot/map_ticks.h"
#include "util/io.h"

namespace topocal::plot {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const cv::Scalar kBlack(0, 0, 0), kWhite(255, 255, 255), kContourColour(30, 30, 30);
constexpr std::uint8_t kNoDataGrey = 205;  // light grey, clearly apart from the white page and from every scale colour

int OpenCvColormap(ColourScale s) { return s == ColourScale::kJet ? cv::COLORMAP_JET : cv::COLORMAP_TURBO; }

// The 256 colours of the scale, as a 256 x 1 BGR image (index 0 = low end).
cv::Mat ScaleLut(ColourScale s) {
  cv::Mat ramp(256, 1, CV_8UC1);
  for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(i) = static_cast<std::uint8_t>(i);
  cv::Mat lut;
  cv::applyColorMap(ramp, lut, OpenCvColormap(s));
  return lut;
}

}  // namespace

bool MapImageOptions::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (size_px < 100 || size_px > 8000) return fail("size_px must be in [100, 8000]");
  if (value_min && !std::isfinite(*value_min)) return fail("value_min must be finite");
  if (value_max && !std::isfinite(*value_max)) return fail("value_max must be finite");
  if (value_min && value_max && !(*value_max > *value_min)) return fail("value_max must exceed value_min");
  if (!std::isfinite(contour_step)) return fail("contour_step must be finite");
  if (!eye.empty() && eye != "OD" && eye != "OS") return fail("eye must be OD, OS or empty");
  return true;
}

std::array<std::uint8_t, 3> ScaleColour(ColourScale scale, double t) {
  static const cv::Mat turbo = ScaleLut(ColourScale::kTurbo), jet = ScaleLut(ColourScale::kJet);
  const cv::Mat& lut = scale == ColourScale::kJet ? jet : turbo;
  const int i = static_cast<int>(std::lround(255.0 * std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0)));
  const auto& c = lut.at<cv::Vec3b>(i);
  return {c[0], c[1], c[2]};
}

std::array<std::uint8_t, 3> NoDataColour() { return {kNoDataGrey, kNoDataGrey, kNoDataGrey}; }

// The eye's sides at the middle of the plot's edges, in the examiner's view (docs/maps.md, "Eye"): superior at
// the top, inferior at the bottom; for OD nasal on the right, for OS on the left. Each letter in a white box with a
// black rim, so that it reads on every colour.
void DrawEyeSides(cv::Mat& img, const cv::Rect& plot, const std::string& eye, const Font& f) {
  if (eye != "OD" && eye != "OS") return;
  const bool od = eye == "OD";
  const int pad = std::max(2, f.height_px / 5);
  const cv::Size box(f.height_px + 2 * pad, f.height_px + 2 * pad);
  const int cx = plot.x + plot.width / 2, cy = plot.y + plot.height / 2;
  const std::pair<const char*, cv::Point> sides[] = {
      {"S", {cx - box.width / 2, plot.y + pad}},
      {"I", {cx - box.width / 2, plot.y + plot.height - box.height - pad}},
      {od ? "T" : "N", {plot.x + pad, cy - box.height / 2}},
      {od ? "N" : "T", {plot.x + plot.width - box.width - pad, cy - box.height / 2}}};
  for (const auto& [letter, corner] : sides) {
    const cv::Rect r(corner, box);
    img(r).setTo(kWhite);
    cv::rectangle(img, r, kBlack, 1);
    PutCentred(img, letter, {r.x + r.width / 2, r.y + pad + f.height_px * 85 / 100}, f);
  }
}

namespace {

// The colour range, its labelled ticks and the contour levels of one map.
struct ColourRange {
  double vmin, vmax;
  bool stepped;         // a stepped (absolute) scale: every step boundary labelled
  double tick_step;
  double contour_step;  // 0: no contours
  double level_origin;  // contour levels at level_origin + k contour_step
  bool banded;          // a stepped palette: one colour per contour band
};

// The palette fraction of value v: its place in the range; on a stepped palette that of the middle of its contour
// band (the band boundaries are the contour levels; values beyond the range take the end bands' colours).
double PaletteFraction(const ColourRange& c, double v) {
  if (c.banded) {
    const double first = std::floor((c.vmin - c.level_origin) / c.contour_step + 1e-9);
    const double last = std::max(first, std::ceil((c.vmax - c.level_origin) / c.contour_step - 1e-9) - 1);
    const double band = std::clamp(std::floor((v - c.level_origin) / c.contour_step), first, last);
    v = c.level_origin + (band + 0.5) * c.contour_step;
  }
  return std::clamp((v - c.vmin) / (c.vmax - c.vmin), 0.0, 1.0);
}

// The options' range, else the data's rounded out to round ticks.
ColourRange ColourRangeOf(const GridMap& map, const MapImageOptions& options) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : map.values) {
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  if (!std::isfinite(lo)) lo = 0.0, hi = 1.0;
  if (hi - lo < 1e-9 * std::max(1.0, std::abs(hi))) {  // a flat field: a unit-wide range around it
    lo -= 0.5;
    hi += 0.5;
  }
  ColourRange c;
  c.vmin = options.value_min.value_or(lo);
  c.vmax = options.value_max.value_or(hi);
  if (options.value_min && !options.value_max && !(c.vmax > c.vmin)) c.vmax = c.vmin + 1.0;
  if (options.value_max && !options.value_min && !(c.vmax > c.vmin)) c.vmin = c.vmax - 1.0;
  // Labelled ticks: 4 to 9 round ones; on a stepped (absolute) scale of up to 16 steps, every step boundary.
  c.stepped = options.contour_step > 0 && options.value_min && options.value_max &&
              (*options.value_max - *options.value_min) / options.contour_step <= 16.0 + 1e-9;
  c.tick_step = c.stepped ? options.contour_step : NiceStep(c.vmax - c.vmin, 8.0);
  if (!options.value_min) c.vmin = c.tick_step * std::floor(c.vmin / c.tick_step + 1e-9);
  if (!options.value_max) c.vmax = c.tick_step * std::ceil(c.vmax / c.tick_step - 1e-9);
  c.contour_step = options.contour_step > 0   ? options.contour_step
                   : options.contour_step < 0 ? 0.0
                                              : NiceStep(c.vmax - c.vmin, 10.0);
  // Contour levels at origin + k step: the band boundaries of a stepped (absolute) scale start at its low end
  // (35.5, 37, ... D), round levels elsewhere start at 0.
  c.level_origin = c.stepped ? c.vmin : 0.0;
  c.banded = options.stepped_palette && c.contour_step > 0;
  return c;
}

// Where everything goes on the image, and the text it carries.
struct MapLayout {
  Font label_font{0}, title_font{0}, small_font{0};
  double wx = 0, wy = 0, px_per_mm = 0;  // the map's extent (mm) and scale
  int plot_w = 0, plot_h = 0;
  int s = 0;  // layout unit
  int line_h = 0, tick_len = 0, y_label_w = 0, y_axis_label_x = 0;
  double axis_step_mm = 0;
  std::vector<std::string> title_lines, footer;
  int title_h = 0;
  cv::Rect plot, bar;
  int width = 0, height = 0;
};

// "beyond the scale" when some of the map lies outside the colour range (drawn in the end colours), from its
// samples with data; empty otherwise.
std::string BeyondScaleLine(const GridMap& map, const ColourRange& c) {
  int with_data = 0, below = 0, above = 0;
  for (double v : map.values) {
    if (!std::isfinite(v)) continue;
    ++with_data;
    below += v < c.vmin ? 1 : 0;
    above += v > c.vmax ? 1 : 0;
  }
  if (below + above == 0) return {};
  const auto pct = [&](int n) { return fmt::format("{:.0f} %", std::max(1.0, std::round(100.0 * n / with_data))); };
  std::string beyond = "beyond the scale (end colours):";
  if (below) beyond += fmt::format(" {} below {:.{}f} {}", pct(below), c.vmin, Decimals(c.tick_step), map.unit);
  if (above) {
    beyond +=
        fmt::format("{} {} above {:.{}f} {}", below ? ";" : "", pct(above), c.vmax, Decimals(c.tick_step), map.unit);
  }
  return beyond;
}

// Footer lines under the x axis: the scale, the contour step, the eye and orientation, the legend (wrapped at word
// boundaries to the image's width: a long number list must not run off the page), what lies beyond the scale.
std::vector<std::string> FooterLines(const GridMap& map, const MapImageOptions& options, const ColourRange& c,
                                     const Font& small_font, int max_width_px) {
  std::vector<std::string> footer;
  if (!options.scale_label.empty()) footer.push_back(options.scale_label);
  if (c.contour_step > 0)
    footer.push_back(fmt::format("contours every {:.{}f} {}", c.contour_step, Decimals(c.contour_step), map.unit));
  if (options.eye.empty()) {
    footer.push_back("test surface (no eye); " + options.orientation);
  } else {
    footer.push_back(fmt::format("eye {} ({}): N nasal, T temporal, S superior, I inferior", options.eye,
                                 options.eye == "OD" ? "right" : "left"));
    footer.push_back("examiner's view; " + options.orientation);
  }
  for (const std::string& line : options.legend) {
    for (std::string& wrapped : WrapText(line, small_font, max_width_px, "  ")) footer.push_back(std::move(wrapped));
  }
  if (std::string beyond = BeyondScaleLine(map, c); !beyond.empty()) footer.push_back(std::move(beyond));
  return footer;
}

MapLayout LayoutOf(const GridMap& map, const MapImageOptions& options, const ColourRange& c) {
  MapLayout l;
  // Geometry: square pixels, equal mm scale on both axes; the longer side gets size_px. Text scales with the plot so
  // that a map printed 90 mm wide (two side by side on A4) has labels of about 8 pt: the label em is 1/20 of the plot.
  l.label_font = Font{std::max(12, static_cast<int>(std::lround(options.size_px / 20.0)))};
  l.title_font = Font{static_cast<int>(std::lround(l.label_font.height_px * 1.2))};
  l.small_font = Font{std::max(11, static_cast<int>(std::lround(l.label_font.height_px * 0.85)))};
  l.wx = map.x_max_mm - map.x_min_mm, l.wy = map.y_max_mm - map.y_min_mm;
  l.px_per_mm = options.size_px / std::max(l.wx, l.wy);
  l.plot_w = std::max(2, static_cast<int>(std::lround(l.wx * l.px_per_mm)));
  l.plot_h = std::max(2, static_cast<int>(std::lround(l.wy * l.px_per_mm)));
  const int s = l.s = std::max(4, l.label_font.height_px / 3);
  l.line_h = l.label_font.height_px + s;
  // Left margin: the y tick labels, a gap, the vertical axis label (its rotated patch is twice the em high).
  l.axis_step_mm = NiceStep(std::max(l.wx, l.wy), 8.0);
  for (double y : Ticks(map.y_min_mm, map.y_max_mm, l.axis_step_mm)) {
    l.y_label_w =
        std::max(l.y_label_w, TextSize(fmt::format("{:.{}f}", y, Decimals(l.axis_step_mm)), l.label_font).width);
  }
  l.tick_len = std::max(4, s / 2);
  // Title (wrapped at its " - " into two lines when it is wider than the image), annotation lines, and a line for
  // the colour bar's unit above the plot. The image's width does not depend on the header.
  const int image_w = (l.y_label_w + 2 * l.label_font.height_px + 4 + 2 * s + s / 2 + l.tick_len) + l.plot_w + 4 * s +
                      std::max(8, 2 * s) + 14 * s;
  l.title_lines = {map.title};
  if (TextSize(map.title, l.title_font).width > image_w - 2 * s) {
    for (const char* sep : {" - ", " \u2014 ", ", "}) {
      const std::size_t at = map.title.rfind(sep);
      if (at == std::string::npos) continue;
      l.title_lines = {map.title.substr(0, at), map.title.substr(at + std::string(sep).size())};
      break;
    }
  }
  l.title_h = static_cast<int>(l.title_lines.size()) * (l.title_font.height_px + s);
  const int header = l.title_h + s + static_cast<int>(options.annotations.size()) * l.line_h + l.line_h + s;
  l.footer = FooterLines(map, options, c, l.small_font, image_w - 2 * s);
  l.y_axis_label_x = s + l.label_font.height_px + 2;  // centre of the rotated "y (mm)"
  l.plot = cv::Rect(l.y_axis_label_x + l.label_font.height_px + 2 + s + l.y_label_w + s / 2 + l.tick_len, header,
                    l.plot_w, l.plot_h);
  l.bar = cv::Rect(l.plot.x + l.plot.width + 4 * s, l.plot.y, std::max(8, 2 * s), l.plot.height);
  l.width = l.bar.x + l.bar.width + 14 * s;
  l.height = l.plot.y + l.plot.height + 2 * l.line_h + static_cast<int>(l.footer.size()) * l.line_h + 2 * s;
  return l;
}

// The field at every plot pixel centre (bilinear, cv::remap), NaN where there is no data, and the mask of pixels
// with data. No data is carried as a weight: a pixel has data where at least half of its interpolation weight comes
// from samples with data.
std::pair<cv::Mat, cv::Mat> SampleField(const GridMap& map, const MapLayout& l) {
  cv::Mat values(map.ny, map.nx, CV_32FC1), weights(map.ny, map.nx, CV_32FC1);
  for (int j = 0; j < map.ny; ++j) {
    for (int i = 0; i < map.nx; ++i) {
      const double v = map.At(i, j);
      values.at<float>(j, i) = std::isfinite(v) ? static_cast<float>(v) : 0.0f;
      weights.at<float>(j, i) = std::isfinite(v) ? 1.0f : 0.0f;
    }
  }
  cv::Mat map_x(l.plot_h, l.plot_w, CV_32FC1), map_y(l.plot_h, l.plot_w, CV_32FC1);
  for (int r = 0; r < l.plot_h; ++r) {
    const double y_mm = map.y_max_mm - (r + 0.5) * l.wy / l.plot_h;
    for (int c = 0; c < l.plot_w; ++c) {
      const double x_mm = map.x_min_mm + (c + 0.5) * l.wx / l.plot_w;
      map_x.at<float>(r, c) = static_cast<float>((x_mm - map.x_min_mm) / l.wx * (map.nx - 1));
      map_y.at<float>(r, c) = static_cast<float>((y_mm - map.y_min_mm) / l.wy * (map.ny - 1));
    }
  }
  cv::Mat sampled, sampled_w;
  cv::remap(values, sampled, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::remap(weights, sampled_w, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::Mat field(l.plot_h, l.plot_w, CV_64FC1);
  cv::Mat valid(l.plot_h, l.plot_w, CV_8UC1);
  for (int r = 0; r < l.plot_h; ++r) {
    for (int c = 0; c < l.plot_w; ++c) {
      const float w = sampled_w.at<float>(r, c);
      const bool ok = w >= 0.5f;
      valid.at<std::uint8_t>(r, c) = ok ? 255 : 0;
      field.at<double>(r, c) = ok ? sampled.at<float>(r, c) / w : kNaN;
    }
  }
  return {field, valid};
}


// Contour lines at the levels: a pixel is on a line where the level band floor((v - origin) / step) changes to its
// right or below it (both pixels with data). This is the pixel-level form of marching squares, exact to a pixel at
// the plot's resolution; cv::findContours would trace the same boundaries plus the no-data edges.
void DrawContours(const cv::Mat& field, const cv::Mat& valid, const ColourRange& c, cv::Mat* coloured) {
  const int h = field.rows, w = field.cols;
  cv::Mat band(h, w, CV_32SC1, cv::Scalar(0));
  for (int r = 0; r < h; ++r) {
    for (int col = 0; col < w; ++col) {
      if (valid.at<std::uint8_t>(r, col)) {
        band.at<int>(r, col) = static_cast<int>(std::floor((field.at<double>(r, col) - c.level_origin) / c.contour_step));
      }
    }
  }
  for (int r = 0; r < h; ++r) {
    for (int col = 0; col < w; ++col) {
      if (!valid.at<std::uint8_t>(r, col)) continue;
      const int b = band.at<int>(r, col);
      const bool right = col + 1 < w && valid.at<std::uint8_t>(r, col + 1) && band.at<int>(r, col + 1) != b;
      const bool edge_below = r + 1 < h && valid.at<std::uint8_t>(r + 1, col) && band.at<int>(r + 1, col) != b;
      if (right || edge_below) coloured->at<cv::Vec3b>(r, col) = cv::Vec3b(30, 30, 30);
    }
  }
}

// The plot's colours: the value's palette fraction (PaletteFraction) through the scale's 256-entry table (OpenCV
// applyColorMap), no-data grey, and the contour lines.
cv::Mat ColouredPlot(const cv::Mat& field, const cv::Mat& valid, const ColourRange& c, ColourScale scale) {
  cv::Mat index(field.rows, field.cols, CV_8UC1, cv::Scalar(0));
  for (int r = 0; r < field.rows; ++r) {
    for (int col = 0; col < field.cols; ++col) {
      if (!valid.at<std::uint8_t>(r, col)) continue;
      const double t = PaletteFraction(c, field.at<double>(r, col));
      index.at<std::uint8_t>(r, col) = static_cast<std::uint8_t>(std::lround(255.0 * t));
    }
  }
  cv::Mat coloured;
  cv::applyColorMap(index, coloured, OpenCvColormap(scale));
  coloured.setTo(cv::Scalar(kNoDataGrey, kNoDataGrey, kNoDataGrey), ~valid);
  if (c.contour_step > 0) DrawContours(field, valid, c, &coloured);
  return coloured;
}

// Axes in mm: ticks and labels on the left and bottom.
void DrawAxes(cv::Mat& img, const GridMap& map, const MapLayout& l) {
  const cv::Rect& plot = l.plot;
  const double axis_step = l.axis_step_mm;
  for (double x : Ticks(map.x_min_mm, map.x_max_mm, axis_step)) {
    const int c = plot.x + static_cast<int>(std::lround((x - map.x_min_mm) / l.wx * l.plot_w));
    cv::line(img, {c, plot.y + plot.height}, {c, plot.y + plot.height + l.tick_len}, kBlack, 1);
    PutCentred(img, fmt::format("{:.{}f}", x, Decimals(axis_step)), {c, plot.y + plot.height + l.tick_len + 2 * l.s},
               l.label_font);
  }
  for (double y : Ticks(map.y_min_mm, map.y_max_mm, axis_step)) {
    const int r = plot.y + plot.height - static_cast<int>(std::lround((y - map.y_min_mm) / l.wy * l.plot_h));
    cv::line(img, {plot.x - l.tick_len, r}, {plot.x - 1, r}, kBlack, 1);
    PutRightMiddle(img, fmt::format("{:.{}f}", y, Decimals(axis_step)), {plot.x - l.tick_len - l.s / 2, r},
                   l.label_font);
  }
  PutCentred(img, "x (mm)", {plot.x + plot.width / 2, plot.y + plot.height + 2 * l.line_h}, l.label_font);
  PutVertical(img, "y (mm)", {l.y_axis_label_x, plot.y + plot.height / 2}, l.label_font);
}

// Rings about the origin (the sim-K zone's meridian ring, when the caller gives one): dashed black on white.
void DrawRings(cv::Mat& img, const GridMap& map, const MapImageOptions& options, const MapLayout& l) {
  for (double ring_mm : options.ring_radii_mm) {
    if (!(ring_mm > 0) || !std::isfinite(ring_mm)) continue;
    const cv::Point centre(l.plot.x + static_cast<int>(std::lround((0 - map.x_min_mm) * l.px_per_mm)),
                           l.plot.y + l.plot.height - static_cast<int>(std::lround((0 - map.y_min_mm) * l.px_per_mm)));
    const int radius = static_cast<int>(std::lround(ring_mm * l.px_per_mm));
    cv::Mat roi = img(l.plot);
    const cv::Point c_in_plot = centre - cv::Point(l.plot.x, l.plot.y);
    cv::circle(roi, c_in_plot, radius, kWhite, 3, cv::LINE_AA);
    for (int deg = 0; deg < 360; deg += 10) {
      cv::ellipse(roi, c_in_plot, {radius, radius}, 0, deg, deg + 5, kBlack, 2, cv::LINE_AA);
    }
  }
}

// Clinical overlays, clipped to the plot: the supported disc (stripes beyond it), the axes, the markers. Map point
// (x, y) mm -> plot pixel, as the sampling: column (x - x_min) px_per_mm - 0.5, row (y_max - y) px_per_mm - 0.5.
class Overlay {
 public:
  Overlay(cv::Mat& img, const GridMap& map, const MapImageOptions& options, const MapLayout& l)
      : roi_(img(l.plot)), map_(map), options_(options), l_(l), line_px_(std::max(2, options.size_px / 400)) {}
  void SupportedDisc(const cv::Mat& valid);
  void Axes();
  void Markers();

 private:
  // Sub-pixel drawing: OpenCV's shift of 4 fractional bits.
  static constexpr int kShift = 4;
  static cv::Point Fixed(const cv::Point2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x * 16)), static_cast<int>(std::lround(p.y * 16)));
  }
  cv::Point2d ToPx(double x_mm, double y_mm) const {
    return cv::Point2d((x_mm - map_.x_min_mm) * l_.px_per_mm - 0.5, (map_.y_max_mm - y_mm) * l_.px_per_mm - 0.5);
  }
  cv::Mat roi_;
  const GridMap& map_;
  const MapImageOptions& options_;
  const MapLayout& l_;
  const int line_px_;
};

// Beyond the supported radius: white diagonal stripes over the colours (half of every 8-pixel period, blended half
// way), so that the extrapolated part is seen at a glance and its values can still be read; the circle itself in
// long black dashes on a white underlay.
void Overlay::SupportedDisc(const cv::Mat& valid) {
  if (!(options_.supported_radius_mm > 0) || !std::isfinite(options_.supported_radius_mm)) return;
  const cv::Point2d origin = ToPx(0, 0);
  const double r_px = options_.supported_radius_mm * l_.px_per_mm;
  for (int r = 0; r < l_.plot_h; ++r) {
    for (int c = 0; c < l_.plot_w; ++c) {
      if (!valid.at<std::uint8_t>(r, c) || (r + c) % 8 >= 3) continue;
      if (std::hypot(c - origin.x, r - origin.y) <= r_px + 0.5 * line_px_ + 1) continue;
      cv::Vec3b& px = roi_.at<cv::Vec3b>(r, c);
      for (int ch = 0; ch < 3; ++ch) px[ch] = static_cast<std::uint8_t>((px[ch] + 255 + 1) / 2);
    }
  }
  const int radius = static_cast<int>(std::lround(r_px * 16));
  cv::circle(roi_, Fixed(origin), radius, kWhite, line_px_ + 2, cv::LINE_AA, kShift);
  for (int deg = 0; deg < 360; deg += 8) {
    cv::ellipse(roi_, Fixed(origin), {radius, radius}, 0, deg, deg + 5, kBlack, line_px_, cv::LINE_AA, kShift);
  }
}

void Overlay::Axes() {
  for (const MapAxis& axis : options_.axes) {
    if (!(axis.half_length_mm > 0) || !std::isfinite(axis.half_length_mm + axis.angle_deg)) continue;
    const double a = axis.angle_deg * M_PI / 180.0;
    const cv::Point2d dir(std::cos(a), std::sin(a));
    const cv::Point2d p0 = ToPx(-axis.half_length_mm * dir.x, -axis.half_length_mm * dir.y);
    const cv::Point2d p1 = ToPx(axis.half_length_mm * dir.x, axis.half_length_mm * dir.y);
    cv::line(roi_, Fixed(p0), Fixed(p1), kWhite, line_px_ + 2, cv::LINE_AA, kShift);
    if (!axis.dashed) {
      cv::line(roi_, Fixed(p0), Fixed(p1), kBlack, line_px_, cv::LINE_AA, kShift);
      continue;
    }
    const double length = std::hypot(p1.x - p0.x, p1.y - p0.y);
    const double dash = 4.0 * line_px_ + 4;
    for (double t = 0; t < length; t += 2 * dash) {
      const cv::Point2d a0 = p0 + (p1 - p0) * (t / length);
      const cv::Point2d a1 = p0 + (p1 - p0) * (std::min(length, t + dash) / length);
      cv::line(roi_, Fixed(a0), Fixed(a1), kBlack, line_px_, cv::LINE_AA, kShift);
    }
  }
}

void Overlay::Markers() {
  const int marker_px = std::max(5, options_.size_px / 100);
  const cv::Scalar marker_colour(kMarkerBgr[0], kMarkerBgr[1], kMarkerBgr[2]);
  for (const MapMarker& m : options_.markers) {
    if (!std::isfinite(m.x_mm + m.y_mm)) continue;
    const cv::Point at = Fixed(ToPx(m.x_mm, m.y_mm));
    cv::circle(roi_, at, (marker_px + 3) * 16, kBlack, cv::FILLED, cv::LINE_AA, kShift);
    cv::circle(roi_, at, (marker_px + 2) * 16, kWhite, cv::FILLED, cv::LINE_AA, kShift);
    // The core without anti-aliasing: its pixels are exactly the marker colour.
    cv::circle(roi_, at, marker_px * 16, marker_colour, cv::FILLED, cv::LINE_8, kShift);
  }
}

// The title and the caller's annotation lines (sim-K etc.) above the plot; the footer lines below it.
void DrawHeaderAndFooter(cv::Mat& img, const MapImageOptions& options, const MapLayout& l) {
  for (std::size_t k = 0; k < l.title_lines.size(); ++k) {
    PutCentred(img, l.title_lines[k],
               {l.width / 2, l.s + l.title_font.height_px + static_cast<int>(k) * (l.title_font.height_px + l.s)},
               l.title_font);
  }
  for (std::size_t k = 0; k < options.annotations.size(); ++k) {
    PutCentred(img, options.annotations[k], {l.width / 2, l.title_h + static_cast<int>(k + 1) * l.line_h - l.s},
               l.label_font);
  }
  for (std::size_t k = 0; k < l.footer.size(); ++k) {
    PutText(img, l.footer[k], {l.s, l.plot.y + l.plot.height + 2 * l.line_h + static_cast<int>(k + 1) * l.line_h},
            l.small_font);
  }
}

// Colour bar: value_max at the top row, value_min at the bottom row; labelled ticks on the right, the contour
// levels as short marks on the left, the unit above.
void DrawColourBar(cv::Mat& img, const GridMap& map, const MapImageOptions& options, const MapLayout& l,
                   const ColourRange& c) {
  const cv::Rect& bar = l.bar;
  const cv::Mat lut = ScaleLut(options.scale);
  for (int r = 0; r < bar.height; ++r) {
    const double t = PaletteFraction(c, c.vmax - (c.vmax - c.vmin) * r / (bar.height - 1));
    const auto& colour = lut.at<cv::Vec3b>(static_cast<int>(std::lround(255.0 * t)));
    img(cv::Rect(bar.x, bar.y + r, bar.width, 1)).setTo(cv::Scalar(colour[0], colour[1], colour[2]));
  }
  cv::rectangle(img, {bar.x - 1, bar.y - 1}, {bar.x + bar.width, bar.y + bar.height}, kBlack, 1);
  const auto bar_row = [&](double v) {
    return bar.y + static_cast<int>(std::lround((c.vmax - v) / (c.vmax - c.vmin) * (bar.height - 1)));
  };
  for (double v : c.stepped ? StepTicks(c.vmin, c.vmax, c.tick_step) : Ticks(c.vmin, c.vmax, c.tick_step)) {
    const int r = bar_row(v);
    cv::line(img, {bar.x + bar.width, r}, {bar.x + bar.width + l.tick_len, r}, kBlack, 1);
    PutLeftMiddle(img, fmt::format("{:.{}f}", v, Decimals(c.tick_step)), {bar.x + bar.width + l.tick_len + l.s / 2, r},
                  l.label_font);
  }
  if (c.contour_step > 0 && (c.vmax - c.vmin) / c.contour_step <= 200) {
    for (double v : c.stepped ? StepTicks(c.vmin, c.vmax, c.contour_step) : Ticks(c.vmin, c.vmax, c.contour_step)) {
      const int r = bar_row(v);
      cv::line(img, {bar.x - l.tick_len, r}, {bar.x - 2, r}, kContourColour, 1);
    }
  }
  // The unit above the bar, clear of the top tick label (centred on the bar's top row).
  PutCentred(img, map.unit, {bar.x + bar.width / 2, bar.y - l.label_font.height_px * 6 / 10 - l.s / 2}, l.label_font);
}

}  // namespace

MapImage RenderMap(const GridMap& map, const MapImageOptions& options) {
  std::string why;
  if (!map.IsValid(&why)) throw util::InputError("GridMap: " + why);
  if (!options.IsValid(&why)) throw util::InputError("MapImageOptions: " + why);
  const ColourRange c = ColourRangeOf(map, options);
  const MapLayout l = LayoutOf(map, options, c);
  cv::Mat img(l.height, l.width, CV_8UC3, kWhite);
  const auto [field, valid] = SampleField(map, l);
  ColouredPlot(field, valid, c, options.scale).copyTo(img(l.plot));
  cv::rectangle(img, {l.plot.x - 1, l.plot.y - 1}, {l.plot.x + l.plot.width, l.plot.y + l.plot.height}, kBlack, 1);
  DrawAxes(img, map, l);
  DrawRings(img, map, options, l);
  Overlay overlay(img, map, options, l);
  overlay.SupportedDisc(valid);
  overlay.Axes();
  overlay.Markers();
  DrawEyeSides(img, l.plot, options.eye, l.label_font);
  DrawHeaderAndFooter(img, options, l);
  DrawColourBar(img, map, options, l, c);

  MapImage out;
  out.width_px = l.width;
  out.height_px = l.height;
  out.bgr.assign(img.datastart, img.dataend);
  out.plot = {l.plot.x, l.plot.y, l.plot.width, l.plot.height};
  out.colour_bar = {l.bar.x, l.bar.y, l.bar.width, l.bar.height};
  out.value_min = c.vmin;
  out.value_max = c.vmax;
  out.contour_step = c.contour_step;
  out.px_per_mm = l.px_per_mm;
  out.x_min_mm = map.x_min_mm;
  out.y_max_mm = map.y_max_mm;
  return out;
}

}  // namespace topocal::plot
