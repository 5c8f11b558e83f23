#include "plot/map_image.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/freetype.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "imageio/image_file.h"
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

// A round step (1, 2 or 5 times a power of ten) of at least range / target_count.
double NiceStep(double range, double target_count) {
  const double raw = range / target_count;
  if (!(raw > 0) || !std::isfinite(raw)) return 1.0;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double f : {1.0, 2.0, 5.0, 10.0}) {
    if (f * mag >= raw * (1 - 1e-9)) return f * mag;
  }
  return 10.0 * mag;
}

// At most this many ticks or band boundaries on a colour bar: the loops below are counted, not stepped, so that a
// step below the values' rounding (1e16 + 1 over a step of 0.2) or a huge range cannot make them run or allocate
// without bound; the two ends stand in where no such scale exists.
constexpr double kMaxTicks = 1000;

std::vector<double> Ticks(double lo, double hi, double step) {
  const double eps = 1e-9 * step;
  const double first = std::ceil((lo - eps) / step);
  const double count = std::floor((hi + eps) / step) - first + 1;
  if (!std::isfinite(first) || !std::isfinite(count) || count > kMaxTicks || std::abs(first) > 1e15) {
    return {lo, hi};
  }
  std::vector<double> t;
  for (int i = 0; i < static_cast<int>(count); ++i) {
    const double v = (first + i) * step;
    t.push_back(std::abs(v) < eps ? 0.0 : v);
  }
  return t;
}

// Decimals that print every multiple of `step` exactly (1.5 -> 1, 0.25 -> 2, 5 -> 0).
// value_min + k step up to value_max: the band boundaries of a stepped scale.
std::vector<double> StepTicks(double lo, double hi, double step) {
  const double count = std::floor((hi - lo) / step + 1e-9) + 1;
  if (!std::isfinite(count) || count > kMaxTicks || !(count >= 1)) return {lo, hi};
  std::vector<double> t;
  for (int k = 0; k < static_cast<int>(count); ++k) t.push_back(lo + k * step);
  return t;
}

int Decimals(double step) {
  for (int k = 0; k < 9; ++k) {
    const double scaled = step * std::pow(10.0, k);
    if (std::abs(scaled - std::round(scaled)) < 1e-6 * std::max(1.0, scaled)) return k;
  }
  return 9;
}

// OpenCV's Hershey fonts are ASCII only: transliterate the few symbols our titles and units use. "µ" is kept as
// a marker (\x01) and drawn as a 'u' with a descender, which reads as µ.
std::string Transliterate(std::string_view s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      out += static_cast<char>(c);
      continue;
    }
    const std::string_view rest = s.substr(i);
    const auto starts = [&](std::string_view p) { return rest.substr(0, p.size()) == p; };
    if (starts("\u00b5") || starts("\u03bc"))
      out += '\x01', i += 1;
    else if (starts("\u03c3"))
      out += "sigma", i += 1;
    else if (starts("\u00b2"))
      out += "^2", i += 1;
    else if (starts("\u00b0"))
      out += " deg", i += 1;
    else if (starts("\u2212"))
      out += '-', i += 2;
    else {
      out += '?';
      while (i + 1 < s.size() && (static_cast<unsigned char>(s[i + 1]) & 0xC0) == 0x80) ++i;
    }
  }
  return out;
}

// Text is drawn with FreeType (OpenCV's freetype module, HarfBuzz shaping) in DejaVu Sans, so that µ, ², °, σ and
// − print as themselves; OpenCV's own Hershey fonts are ASCII only. Without the font file (Debian fonts-dejavu-core,
// installed by scripts/setup.sh) the Hershey font is used with the transliteration above.
constexpr const char* kFontPath = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

// One FreeType renderer per thread (calibrate-batch draws maps from several threads; the renderer has state).
cv::freetype::FreeType2* TrueType() {
  thread_local cv::Ptr<cv::freetype::FreeType2> ft = [] {
    cv::Ptr<cv::freetype::FreeType2> f;
    if (::access(kFontPath, R_OK) != 0) return f;
    try {
      f = cv::freetype::createFreeType2();
      f->loadFontData(kFontPath, 0);
    } catch (const cv::Exception&) {
      f.release();
    }
    return f;
  }();
  return ft.get();
}

struct Font {
  int height_px;  // em height
};

double HersheyScale(const Font& f) { return f.height_px / 30.0; }
int HersheyThickness(const Font& f) { return std::max(1, static_cast<int>(std::lround(f.height_px / 14.0))); }

cv::Size TextSize(const std::string& text, const Font& f) {
  int baseline = 0;
  if (auto* ft = TrueType()) {
    // Measured once per text and size on each thread (the legend's word wrapping measures each line once
    // per word, the tick labels are measured for the layout and again to be placed, and a record's maps share their
    // legends; FreeType shapes and hints every glyph anew on each call: ~3 % of unit calibrate's CPU). A measure
    // depends only on the text, the size and the font, so the images are the same bytes.
    thread_local std::map<std::pair<int, std::string>, cv::Size> measured;
    constexpr size_t kMaxMeasured = 4096;  // a long calibrate-batch must not grow it without bound
    const auto key = std::make_pair(f.height_px, text);
    if (const auto it = measured.find(key); it != measured.end()) return it->second;
    if (measured.size() >= kMaxMeasured) measured.clear();
    const cv::Size size = ft->getTextSize(text, f.height_px, -1, &baseline);
    return measured.emplace(key, cv::Size{size.width, size.height}).first->second;
  }
  std::string ascii = Transliterate(text);
  std::replace(ascii.begin(), ascii.end(), '\x01', 'u');
  return cv::getTextSize(ascii, cv::FONT_HERSHEY_SIMPLEX, HersheyScale(f), HersheyThickness(f), &baseline);
}

// Draws text with its baseline-left corner at `org`.
void PutText(cv::Mat& img, const std::string& text, cv::Point org, const Font& f, const cv::Scalar& colour = kBlack) {
  if (auto* ft = TrueType()) {
    ft->putText(img, text, org, f.height_px, colour, -1, cv::LINE_AA, true);
    return;
  }
  const std::string marked = Transliterate(text);
  std::string ascii = marked;
  std::replace(ascii.begin(), ascii.end(), '\x01', 'u');
  cv::putText(img, ascii, org, cv::FONT_HERSHEY_SIMPLEX, HersheyScale(f), colour, HersheyThickness(f), cv::LINE_AA);
  // The descender that turns each 'u' standing for µ into a µ.
  for (size_t p = marked.find('\x01'); p != std::string::npos; p = marked.find('\x01', p + 1)) {
    int baseline = 0;
    const auto size = [&](const std::string& t) {
      std::string a = t;
      std::replace(a.begin(), a.end(), '\x01', 'u');
      return cv::getTextSize(a, cv::FONT_HERSHEY_SIMPLEX, HersheyScale(f), HersheyThickness(f), &baseline);
    };
    const int x = org.x + size(marked.substr(0, p)).width;
    const int h = size("u").height;
    const int stem = x + std::max(1, static_cast<int>(std::lround(0.22 * h)));
    cv::line(img, {stem, org.y - h / 2}, {stem, org.y + static_cast<int>(0.45 * h)}, colour, HersheyThickness(f),
             cv::LINE_AA);
  }
}

// Text anchored by its centre (x) and baseline (y), or right-aligned / centred vertically.
void PutCentred(cv::Mat& img, const std::string& text, cv::Point centre_baseline, const Font& f) {
  PutText(img, text, {centre_baseline.x - TextSize(text, f).width / 2, centre_baseline.y}, f);
}

void PutRightMiddle(cv::Mat& img, const std::string& text, cv::Point right_middle, const Font& f) {
  const cv::Size s = TextSize(text, f);
  PutText(img, text, {right_middle.x - s.width, right_middle.y + s.height / 2}, f);
}

void PutLeftMiddle(cv::Mat& img, const std::string& text, cv::Point left_middle, const Font& f) {
  PutText(img, text, {left_middle.x, left_middle.y + TextSize(text, f).height / 2}, f);
}

// Vertical text reading bottom to top, centred at `centre`.
void PutVertical(cv::Mat& img, const std::string& text, cv::Point centre, const Font& f) {
  const cv::Size s = TextSize(text, f);
  cv::Mat patch(s.height * 2 + 4, s.width + 4, CV_8UC3, kWhite);
  PutText(patch, text, {2, s.height + 2}, f);
  cv::Mat rotated;
  cv::rotate(patch, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const cv::Rect dst(centre.x - rotated.cols / 2, centre.y - rotated.rows / 2, rotated.cols, rotated.rows);
  if ((dst & cv::Rect(0, 0, img.cols, img.rows)) == dst) rotated.copyTo(img(dst));
}

}  // namespace

bool GridMap::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (nx < 2 || ny < 2) return fail("the grid needs at least 2 x 2 samples");
  if (!(x_max_mm > x_min_mm) || !(y_max_mm > y_min_mm) || !std::isfinite(x_min_mm + x_max_mm + y_min_mm + y_max_mm)) {
    return fail("the grid's extent must be finite with x_max > x_min and y_max > y_min");
  }
  if (values.size() != static_cast<size_t>(nx) * ny) return fail("values must hold nx * ny samples");
  for (double v : values) {
    if (std::isinf(v)) return fail("values must be finite or NaN (no data)");
  }
  return true;
}

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

MapImage RenderMap(const GridMap& map, const MapImageOptions& options) {
  std::string why;
  if (!map.IsValid(&why)) throw std::invalid_argument("GridMap: " + why);
  if (!options.IsValid(&why)) throw std::invalid_argument("MapImageOptions: " + why);

  // Colour range: the options', else the data's rounded out to round ticks.
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : map.values) {
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  if (!std::isfinite(lo)) lo = 0.0, hi = 1.0;
  if (hi - lo < 1e-9 * std::max(1.0, std::abs(hi))) {  // a flat field: a unit-wide range around it
    lo -= 0.5;
    hi += 0.5;
  }
  double vmin = options.value_min.value_or(lo), vmax = options.value_max.value_or(hi);
  if (options.value_min && !options.value_max && !(vmax > vmin)) vmax = vmin + 1.0;
  if (options.value_max && !options.value_min && !(vmax > vmin)) vmin = vmax - 1.0;
  // Labelled ticks: 4 to 9 round ones; on a stepped (absolute) scale of up to 16 steps, every step boundary.
  const bool stepped = options.contour_step > 0 && options.value_min && options.value_max &&
                       (*options.value_max - *options.value_min) / options.contour_step <= 16.0 + 1e-9;
  const double tick_step = stepped ? options.contour_step : NiceStep(vmax - vmin, 8.0);
  if (!options.value_min) vmin = tick_step * std::floor(vmin / tick_step + 1e-9);
  if (!options.value_max) vmax = tick_step * std::ceil(vmax / tick_step - 1e-9);
  const double contour_step = options.contour_step > 0   ? options.contour_step
                              : options.contour_step < 0 ? 0.0
                                                         : NiceStep(vmax - vmin, 10.0);
  // Contour levels at origin + k step: the band boundaries of a stepped (absolute) scale start at its low end
  // (35.5, 37, ... D), round levels elsewhere start at 0.
  const double level_origin = stepped ? vmin : 0.0;

  // Geometry: square pixels, equal mm scale on both axes; the longer side gets size_px. Text scales with the plot so
  // that a map printed 90 mm wide (two side by side on A4) has labels of about 8 pt: the label em is 1/20 of the plot.
  const Font label_font{std::max(12, static_cast<int>(std::lround(options.size_px / 20.0)))};
  const Font title_font{static_cast<int>(std::lround(label_font.height_px * 1.2))};
  const Font small_font{std::max(11, static_cast<int>(std::lround(label_font.height_px * 0.85)))};
  const double wx = map.x_max_mm - map.x_min_mm, wy = map.y_max_mm - map.y_min_mm;
  const double px_per_mm = options.size_px / std::max(wx, wy);
  const int plot_w = std::max(2, static_cast<int>(std::lround(wx * px_per_mm)));
  const int plot_h = std::max(2, static_cast<int>(std::lround(wy * px_per_mm)));
  const int s = std::max(4, label_font.height_px / 3);  // layout unit
  const int line_h = label_font.height_px + s;
  // Left margin: the y tick labels, a gap, the vertical axis label (its rotated patch is twice the em high).
  const double axis_step_mm = NiceStep(std::max(wx, wy), 8.0);
  int y_label_w = 0;
  for (double y : Ticks(map.y_min_mm, map.y_max_mm, axis_step_mm)) {
    y_label_w = std::max(y_label_w, TextSize(fmt::format("{:.{}f}", y, Decimals(axis_step_mm)), label_font).width);
  }
  const int tick_len = std::max(4, s / 2);
  // Title (wrapped at its " - " into two lines when it is wider than the image), annotation lines, and a line for
  // the colour bar's unit above the plot. The image's width does not depend on the header.
  const int image_w = (y_label_w + 2 * label_font.height_px + 4 + 2 * s + s / 2 + tick_len) + plot_w + 4 * s +
                      std::max(8, 2 * s) + 14 * s;
  std::vector<std::string> title_lines = {map.title};
  if (TextSize(map.title, title_font).width > image_w - 2 * s) {
    for (const char* sep : {" - ", " \u2014 ", ", "}) {
      const std::size_t at = map.title.rfind(sep);
      if (at == std::string::npos) continue;
      title_lines = {map.title.substr(0, at), map.title.substr(at + std::string(sep).size())};
      break;
    }
  }
  const int title_h = static_cast<int>(title_lines.size()) * (title_font.height_px + s);
  const int header = title_h + s + static_cast<int>(options.annotations.size()) * line_h + line_h + s;
  // Footer lines under the x axis: the scale, the contour step, the eye and orientation.
  std::vector<std::string> footer;
  if (!options.scale_label.empty()) footer.push_back(options.scale_label);
  if (contour_step > 0)
    footer.push_back(fmt::format("contours every {:.{}f} {}", contour_step, Decimals(contour_step), map.unit));
  if (options.eye.empty()) {
    footer.push_back("test surface (no eye); " + options.orientation);
  } else {
    footer.push_back(fmt::format("eye {} ({}): N nasal, T temporal, S superior, I inferior", options.eye,
                                 options.eye == "OD" ? "right" : "left"));
    footer.push_back("examiner's view; " + options.orientation);
  }
  // Legend lines wrap at word boundaries to the image's width (a long number list must not run off the page).
  for (const std::string& line : options.legend) {
    std::string current;
    std::size_t start = 0;
    while (start <= line.size()) {
      std::size_t end = line.find(' ', start);
      if (end == std::string::npos) end = line.size();
      const std::string word = line.substr(start, end - start);
      const std::string candidate = current.empty() ? word : current + " " + word;
      if (!current.empty() && TextSize(candidate, small_font).width > image_w - 2 * s) {
        footer.push_back(current);
        current = "  " + word;
      } else {
        current = candidate;
      }
      start = end + 1;
    }
    if (!current.empty()) footer.push_back(current);
  }
  // How much of the map lies beyond the colour range (drawn in the end colours), from its samples with data.
  int with_data = 0, below = 0, above = 0;
  for (double v : map.values) {
    if (!std::isfinite(v)) continue;
    ++with_data;
    below += v < vmin ? 1 : 0;
    above += v > vmax ? 1 : 0;
  }
  if (below + above > 0) {
    const auto pct = [&](int n) { return fmt::format("{:.0f} %", std::max(1.0, std::round(100.0 * n / with_data))); };
    std::string beyond = "beyond the scale (end colours):";
    if (below) beyond += fmt::format(" {} below {:.{}f} {}", pct(below), vmin, Decimals(tick_step), map.unit);
    if (above)
      beyond +=
          fmt::format("{} {} above {:.{}f} {}", below ? ";" : "", pct(above), vmax, Decimals(tick_step), map.unit);
    footer.push_back(beyond);
  }
  const int footer_lines = static_cast<int>(footer.size());
  const int y_axis_label_x = s + label_font.height_px + 2;  // centre of the rotated "y (mm)"
  const cv::Rect plot(y_axis_label_x + label_font.height_px + 2 + s + y_label_w + s / 2 + tick_len, header, plot_w,
                      plot_h);
  const cv::Rect bar(plot.x + plot.width + 4 * s, plot.y, std::max(8, 2 * s), plot.height);
  const int width = bar.x + bar.width + 14 * s;
  const int height = plot.y + plot.height + 2 * line_h + footer_lines * line_h + 2 * s;
  cv::Mat img(height, width, CV_8UC3, kWhite);

  // Sample the field at every plot pixel centre (bilinear, cv::remap). No data is carried as a weight: a pixel has
  // data where at least half of its interpolation weight comes from samples with data.
  cv::Mat values(map.ny, map.nx, CV_32FC1), weights(map.ny, map.nx, CV_32FC1);
  for (int j = 0; j < map.ny; ++j) {
    for (int i = 0; i < map.nx; ++i) {
      const double v = map.At(i, j);
      values.at<float>(j, i) = std::isfinite(v) ? static_cast<float>(v) : 0.0f;
      weights.at<float>(j, i) = std::isfinite(v) ? 1.0f : 0.0f;
    }
  }
  cv::Mat map_x(plot_h, plot_w, CV_32FC1), map_y(plot_h, plot_w, CV_32FC1);
  for (int r = 0; r < plot_h; ++r) {
    const double y_mm = map.y_max_mm - (r + 0.5) * wy / plot_h;
    for (int c = 0; c < plot_w; ++c) {
      const double x_mm = map.x_min_mm + (c + 0.5) * wx / plot_w;
      map_x.at<float>(r, c) = static_cast<float>((x_mm - map.x_min_mm) / wx * (map.nx - 1));
      map_y.at<float>(r, c) = static_cast<float>((y_mm - map.y_min_mm) / wy * (map.ny - 1));
    }
  }
  cv::Mat sampled, sampled_w;
  cv::remap(values, sampled, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::remap(weights, sampled_w, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::Mat field(plot_h, plot_w, CV_64FC1);
  cv::Mat valid(plot_h, plot_w, CV_8UC1);
  for (int r = 0; r < plot_h; ++r) {
    for (int c = 0; c < plot_w; ++c) {
      const float w = sampled_w.at<float>(r, c);
      const bool ok = w >= 0.5f;
      valid.at<std::uint8_t>(r, c) = ok ? 255 : 0;
      field.at<double>(r, c) = ok ? sampled.at<float>(r, c) / w : kNaN;
    }
  }

  // Colour: the value's fraction of the range through the scale's 256-entry table (OpenCV applyColorMap).
  cv::Mat index(plot_h, plot_w, CV_8UC1, cv::Scalar(0));
  for (int r = 0; r < plot_h; ++r) {
    for (int c = 0; c < plot_w; ++c) {
      if (!valid.at<std::uint8_t>(r, c)) continue;
      const double t = std::clamp((field.at<double>(r, c) - vmin) / (vmax - vmin), 0.0, 1.0);
      index.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(std::lround(255.0 * t));
    }
  }
  cv::Mat coloured;
  cv::applyColorMap(index, coloured, OpenCvColormap(options.scale));
  coloured.setTo(cv::Scalar(kNoDataGrey, kNoDataGrey, kNoDataGrey), ~valid);

  // Contour lines at the multiples of the step: a pixel is on a line where the level band floor(v / step) changes
  // to its right or below it (both pixels with data). This is the pixel-level form of marching squares, exact to a
  // pixel at the plot's resolution; cv::findContours would trace the same boundaries plus the no-data edges.
  if (contour_step > 0) {
    cv::Mat band(plot_h, plot_w, CV_32SC1, cv::Scalar(0));
    for (int r = 0; r < plot_h; ++r) {
      for (int c = 0; c < plot_w; ++c) {
        if (valid.at<std::uint8_t>(r, c)) {
          band.at<int>(r, c) = static_cast<int>(std::floor((field.at<double>(r, c) - level_origin) / contour_step));
        }
      }
    }
    for (int r = 0; r < plot_h; ++r) {
      for (int c = 0; c < plot_w; ++c) {
        if (!valid.at<std::uint8_t>(r, c)) continue;
        const int b = band.at<int>(r, c);
        const bool right = c + 1 < plot_w && valid.at<std::uint8_t>(r, c + 1) && band.at<int>(r, c + 1) != b;
        const bool edge_below = r + 1 < plot_h && valid.at<std::uint8_t>(r + 1, c) && band.at<int>(r + 1, c) != b;
        if (right || edge_below) coloured.at<cv::Vec3b>(r, c) = cv::Vec3b(30, 30, 30);
      }
    }
  }
  coloured.copyTo(img(plot));
  cv::rectangle(img, {plot.x - 1, plot.y - 1}, {plot.x + plot.width, plot.y + plot.height}, kBlack, 1);

  // Axes in mm: ticks and labels on the left and bottom, light grid through the ticks.
  const double axis_step = axis_step_mm;
  for (double x : Ticks(map.x_min_mm, map.x_max_mm, axis_step)) {
    const int c = plot.x + static_cast<int>(std::lround((x - map.x_min_mm) / wx * plot_w));
    cv::line(img, {c, plot.y + plot.height}, {c, plot.y + plot.height + tick_len}, kBlack, 1);
    PutCentred(img, fmt::format("{:.{}f}", x, Decimals(axis_step)), {c, plot.y + plot.height + tick_len + 2 * s},
               label_font);
  }
  for (double y : Ticks(map.y_min_mm, map.y_max_mm, axis_step)) {
    const int r = plot.y + plot.height - static_cast<int>(std::lround((y - map.y_min_mm) / wy * plot_h));
    cv::line(img, {plot.x - tick_len, r}, {plot.x - 1, r}, kBlack, 1);
    PutRightMiddle(img, fmt::format("{:.{}f}", y, Decimals(axis_step)), {plot.x - tick_len - s / 2, r}, label_font);
  }
  PutCentred(img, "x (mm)", {plot.x + plot.width / 2, plot.y + plot.height + 2 * line_h}, label_font);
  PutVertical(img, "y (mm)", {y_axis_label_x, plot.y + plot.height / 2}, label_font);

  // Rings about the origin (the sim-K zone's meridian ring, when the caller gives one): dashed black on white.
  for (double ring_mm : options.ring_radii_mm) {
    if (!(ring_mm > 0) || !std::isfinite(ring_mm)) continue;
    const cv::Point centre(plot.x + static_cast<int>(std::lround((0 - map.x_min_mm) * px_per_mm)),
                           plot.y + plot.height - static_cast<int>(std::lround((0 - map.y_min_mm) * px_per_mm)));
    const int radius = static_cast<int>(std::lround(ring_mm * px_per_mm));
    cv::Mat roi = img(plot);
    const cv::Point c_in_plot = centre - cv::Point(plot.x, plot.y);
    cv::circle(roi, c_in_plot, radius, kWhite, 3, cv::LINE_AA);
    for (int deg = 0; deg < 360; deg += 10) {
      cv::ellipse(roi, c_in_plot, {radius, radius}, 0, deg, deg + 5, kBlack, 2, cv::LINE_AA);
    }
  }

  // Clinical overlays, clipped to the plot. Map point (x, y) mm -> plot pixel, as the sampling
  // above: column (x - x_min) px_per_mm - 0.5, row (y_max - y) px_per_mm - 0.5.
  cv::Mat plot_roi = img(plot);
  const auto to_px = [&](double x_mm, double y_mm) {
    return cv::Point2d((x_mm - map.x_min_mm) * px_per_mm - 0.5, (map.y_max_mm - y_mm) * px_per_mm - 0.5);
  };
  // Sub-pixel drawing: OpenCV's shift of 4 fractional bits.
  constexpr int kShift = 4;
  const auto fixed = [](const cv::Point2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x * 16)), static_cast<int>(std::lround(p.y * 16)));
  };
  const int line_px = std::max(2, options.size_px / 400);
  if (options.supported_radius_mm > 0 && std::isfinite(options.supported_radius_mm)) {
    // Beyond the supported radius: white diagonal stripes over the colours (half of every 8-pixel period, blended
    // half way), so that the extrapolated part is seen at a glance and its values can still be read.
    const cv::Point2d origin = to_px(0, 0);
    const double r_px = options.supported_radius_mm * px_per_mm;
    for (int r = 0; r < plot_h; ++r) {
      for (int c = 0; c < plot_w; ++c) {
        if (!valid.at<std::uint8_t>(r, c) || (r + c) % 8 >= 3) continue;
        if (std::hypot(c - origin.x, r - origin.y) <= r_px + 0.5 * line_px + 1) continue;
        cv::Vec3b& px = plot_roi.at<cv::Vec3b>(r, c);
        for (int ch = 0; ch < 3; ++ch) px[ch] = static_cast<std::uint8_t>((px[ch] + 255 + 1) / 2);
      }
    }
    // The circle itself: long black dashes on a white underlay.
    const int radius = static_cast<int>(std::lround(r_px * 16));
    cv::circle(plot_roi, fixed(origin), radius, kWhite, line_px + 2, cv::LINE_AA, kShift);
    for (int deg = 0; deg < 360; deg += 8) {
      cv::ellipse(plot_roi, fixed(origin), {radius, radius}, 0, deg, deg + 5, kBlack, line_px, cv::LINE_AA, kShift);
    }
  }
  for (const MapAxis& axis : options.axes) {
    if (!(axis.half_length_mm > 0) || !std::isfinite(axis.half_length_mm + axis.angle_deg)) continue;
    const double a = axis.angle_deg * M_PI / 180.0;
    const cv::Point2d dir(std::cos(a), std::sin(a));
    const cv::Point2d p0 = to_px(-axis.half_length_mm * dir.x, -axis.half_length_mm * dir.y);
    const cv::Point2d p1 = to_px(axis.half_length_mm * dir.x, axis.half_length_mm * dir.y);
    cv::line(plot_roi, fixed(p0), fixed(p1), kWhite, line_px + 2, cv::LINE_AA, kShift);
    if (!axis.dashed) {
      cv::line(plot_roi, fixed(p0), fixed(p1), kBlack, line_px, cv::LINE_AA, kShift);
      continue;
    }
    const double length = std::hypot(p1.x - p0.x, p1.y - p0.y);
    const double dash = 4.0 * line_px + 4;
    for (double t = 0; t < length; t += 2 * dash) {
      const cv::Point2d a0 = p0 + (p1 - p0) * (t / length);
      const cv::Point2d a1 = p0 + (p1 - p0) * (std::min(length, t + dash) / length);
      cv::line(plot_roi, fixed(a0), fixed(a1), kBlack, line_px, cv::LINE_AA, kShift);
    }
  }
  const int marker_px = std::max(5, options.size_px / 100);
  const cv::Scalar marker_colour(kMarkerBgr[0], kMarkerBgr[1], kMarkerBgr[2]);
  for (const MapMarker& m : options.markers) {
    if (!std::isfinite(m.x_mm + m.y_mm)) continue;
    const cv::Point at = fixed(to_px(m.x_mm, m.y_mm));
    cv::circle(plot_roi, at, (marker_px + 3) * 16, kBlack, cv::FILLED, cv::LINE_AA, kShift);
    cv::circle(plot_roi, at, (marker_px + 2) * 16, kWhite, cv::FILLED, cv::LINE_AA, kShift);
    // The core without anti-aliasing: its pixels are exactly the marker colour.
    cv::circle(plot_roi, at, marker_px * 16, marker_colour, cv::FILLED, cv::LINE_8, kShift);
  }

  DrawEyeSides(img, plot, options.eye, label_font);

  // Title and the caller's annotation lines (sim-K etc.) above the plot.
  for (std::size_t k = 0; k < title_lines.size(); ++k) {
    PutCentred(img, title_lines[k],
               {width / 2, s + title_font.height_px + static_cast<int>(k) * (title_font.height_px + s)}, title_font);
  }
  for (std::size_t k = 0; k < options.annotations.size(); ++k) {
    PutCentred(img, options.annotations[k], {width / 2, title_h + static_cast<int>(k + 1) * line_h - s}, label_font);
  }

  // Colour bar: value_max at the top row, value_min at the bottom row; labelled ticks on the right, the contour
  // levels as short marks on the left, the unit above.
  const cv::Mat lut = ScaleLut(options.scale);
  for (int r = 0; r < bar.height; ++r) {
    const double t = 1.0 - static_cast<double>(r) / (bar.height - 1);
    const auto& colour = lut.at<cv::Vec3b>(static_cast<int>(std::lround(255.0 * t)));
    img(cv::Rect(bar.x, bar.y + r, bar.width, 1)).setTo(cv::Scalar(colour[0], colour[1], colour[2]));
  }
  cv::rectangle(img, {bar.x - 1, bar.y - 1}, {bar.x + bar.width, bar.y + bar.height}, kBlack, 1);
  const auto bar_row = [&](double v) {
    return bar.y + static_cast<int>(std::lround((vmax - v) / (vmax - vmin) * (bar.height - 1)));
  };
  for (double v : stepped ? StepTicks(vmin, vmax, tick_step) : Ticks(vmin, vmax, tick_step)) {
    const int r = bar_row(v);
    cv::line(img, {bar.x + bar.width, r}, {bar.x + bar.width + tick_len, r}, kBlack, 1);
    PutLeftMiddle(img, fmt::format("{:.{}f}", v, Decimals(tick_step)), {bar.x + bar.width + tick_len + s / 2, r},
                  label_font);
  }
  if (contour_step > 0 && (vmax - vmin) / contour_step <= 200) {
    for (double v : stepped ? StepTicks(vmin, vmax, contour_step) : Ticks(vmin, vmax, contour_step)) {
      const int r = bar_row(v);
      cv::line(img, {bar.x - tick_len, r}, {bar.x - 2, r}, kContourColour, 1);
    }
  }
  // The unit above the bar, clear of the top tick label (centred on the bar's top row).
  PutCentred(img, map.unit, {bar.x + bar.width / 2, bar.y - label_font.height_px * 6 / 10 - s / 2}, label_font);
  for (std::size_t k = 0; k < footer.size(); ++k) {
    PutText(img, footer[k], {s, plot.y + plot.height + 2 * line_h + static_cast<int>(k + 1) * line_h}, small_font);
  }

  MapImage out;
  out.width_px = width;
  out.height_px = height;
  out.bgr.assign(img.datastart, img.dataend);
  out.plot = {plot.x, plot.y, plot.width, plot.height};
  out.colour_bar = {bar.x, bar.y, bar.width, bar.height};
  out.value_min = vmin;
  out.value_max = vmax;
  out.contour_step = contour_step;
  out.px_per_mm = px_per_mm;
  out.x_min_mm = map.x_min_mm;
  out.y_max_mm = map.y_max_mm;
  return out;
}

void WriteMapPng(const std::string& path, const GridMap& map, const MapImageOptions& options) {
  MapImage image = RenderMap(map, options);
  imageio::WritePng(path, cv::Mat(image.height_px, image.width_px, CV_8UC3, image.bgr.data()));
}

std::string GridMapCsv(const GridMap& map) {
  std::string why;
  if (!map.IsValid(&why)) throw std::invalid_argument("GridMap: " + why);
  std::string column = "value";
  const std::string unit = Transliterate(map.unit);
  if (!unit.empty()) column += '_';
  for (char c : unit) {
    if (c == '\x01')
      column += 'u';
    else if (std::isalnum(static_cast<unsigned char>(c)))
      column += c;
    else
      column += '_';
  }
  std::string csv = "x_mm,y_mm," + column + "\n";
  csv.reserve(csv.size() + map.values.size() * 32);
  // Each column's x is the same double in every row: formatted once (with its comma) rather than once per value,
  // which was two thirds of the formatting. The text is the same.
  std::vector<std::string> x_text(static_cast<size_t>(map.nx));
  for (int i = 0; i < map.nx; ++i) {
    const double x = map.x_min_mm + i * (map.x_max_mm - map.x_min_mm) / (map.nx - 1);
    x_text[static_cast<size_t>(i)] = fmt::format("{},", x);
  }
  std::string y_text;
  for (int j = 0; j < map.ny; ++j) {
    const double y = map.y_min_mm + j * (map.y_max_mm - map.y_min_mm) / (map.ny - 1);
    y_text = fmt::format("{},", y);
    for (int i = 0; i < map.nx; ++i) {
      const double v = map.At(i, j);
      csv += x_text[static_cast<size_t>(i)];
      csv += y_text;
      // Formatted into a stack buffer: a temporary string per value was a third of the time of writing a unit
      // record's maps. 32 characters hold any double's shortest round-trip form.
      if (std::isfinite(v)) {
        char text[32];
        csv.append(text, fmt::format_to_n(text, sizeof text, "{}", v).out);
      }
      csv += '\n';
    }
  }
  return csv;
}

void WriteMapCsv(const std::string& path, const GridMap& map) { util::WriteFileAtomic(path, GridMapCsv(map)); }

bool MapScaleRequest::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (kind == MapScaleKind::kAbsolute) {
    if (!(step > 0) || !std::isfinite(step)) return fail("an absolute scale needs a finite step > 0");
    if (low.has_value() != high.has_value()) return fail("an absolute scale's low and high go together");
    if (low && !(std::isfinite(*low) && std::isfinite(*high) && *high > *low)) {
      return fail("an absolute scale needs finite low < high");
    }
    if (low) {
      const double steps = (*high - *low) / step;
      if (std::abs(steps - std::round(steps)) > 1e-9 * std::max(1.0, steps)) {
        return fail("an absolute scale's high - low must be a whole number of steps");
      }
    }
  }
  if (!(min_span >= 0) || !std::isfinite(min_span)) return fail("min_span must be finite and >= 0");
  return true;
}

MapScaleRequest FittedStepScale(double step) {
  MapScaleRequest r;
  r.kind = MapScaleKind::kAbsolute;
  r.step = step;
  return r;
}

MapScaleRequest StandardPowerScale() {
  MapScaleRequest r = FittedStepScale(kStandardPowerStepD);
  r.low = kStandardPowerLowD;
  r.high = kStandardPowerHighD;
  return r;
}

MapScaleRequest ExtendedPowerScale() {
  MapScaleRequest r = FittedStepScale(kExtendedPowerStepD);
  r.low = kExtendedPowerLowD;
  r.high = kExtendedPowerHighD;
  return r;
}

MapScaleRequest NormalisedScale(double min_span) {
  MapScaleRequest r;
  r.kind = MapScaleKind::kNormalised;
  r.min_span = min_span;
  return r;
}

MapScale SelectMapScale(const std::vector<const GridMap*>& maps, const MapScaleRequest& request) {
  std::string why;
  if (!request.IsValid(&why)) throw std::invalid_argument("MapScaleRequest: " + why);
  if (maps.empty()) throw std::invalid_argument("SelectMapScale: no map");
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::string unit;
  for (const GridMap* m : maps) {
    if (!m) throw std::invalid_argument("SelectMapScale: null map");
    unit = m->unit;
    for (double v : m->values) {
      if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    }
  }
  const bool has_data = std::isfinite(lo);
  const std::string set_word = maps.size() > 1 ? fmt::format("these {} maps'", maps.size()) : std::string("this map's");
  MapScale out;
  if (request.kind == MapScaleKind::kAbsolute) {
    const double step = request.step;
    double a = 0, b = 0;
    if (request.low) {
      a = *request.low;
      b = *request.high;
      // Widen by whole steps to hold every value (anchored on the standard range's boundaries) when asked.
      if (request.widen_to_data && has_data && lo < a) a -= step * std::ceil((a - lo) / step - 1e-9);
      if (request.widen_to_data && has_data && hi > b) b += step * std::ceil((hi - b) / step - 1e-9);
    } else {
      if (!has_data) lo = 0, hi = 0;
      a = step * std::floor(lo / step + 1e-9);
      b = step * std::ceil(hi / step - 1e-9);
      if (b <= a) b = a + step;
      const int missing = kMinAbsoluteSteps - static_cast<int>(std::lround((b - a) / step));
      if (missing > 0) {
        a -= step * (missing / 2);
        b += step * (missing - missing / 2);
      }
    }
    out.value_min = a;
    out.value_max = b;
    out.contour_step = step;
    out.label = fmt::format("absolute scale, {:.{}f} {} steps", step, Decimals(step), unit);
    return out;
  }
  if (!has_data) lo = 0, hi = 1;
  double span = hi - lo;
  const bool widened = span < request.min_span;
  if (widened) {
    const double mid = 0.5 * (lo + hi);
    lo = mid - 0.5 * request.min_span;
    hi = mid + 0.5 * request.min_span;
    span = request.min_span;
  }
  if (!(span > 0)) {  // a flat field with no minimum span: a unit-wide range around it, as RenderMap does
    lo -= 0.5;
    hi += 0.5;
  }
  const double tick = NiceStep(hi - lo, 8.0);
  out.value_min = tick * std::floor(lo / tick + 1e-9);
  out.value_max = tick * std::ceil(hi / tick - 1e-9);
  out.contour_step = NiceStep(out.value_max - out.value_min, 10.0);
  out.label = fmt::format("normalised: {} range{}", set_word,
                          widened ? fmt::format(", min. span {} {}", request.min_span, unit) : std::string());
  return out;
}

void ApplyMapScale(const MapScale& scale, MapImageOptions* options) {
  options->value_min = scale.value_min;
  options->value_max = scale.value_max;
  options->contour_step = scale.contour_step;
  options->scale_label = scale.label;
}

}  // namespace topocal::plot
