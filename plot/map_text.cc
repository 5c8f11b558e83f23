#include "plot/map_text.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/freetype.hpp>
#include <opencv2/imgproc.hpp>
#include <unistd.h>

namespace topocal::plot {
namespace {

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



double HersheyScale(const Font& f) { return f.height_px / 30.0; }
int HersheyThickness(const Font& f) { return std::max(1, static_cast<int>(std::lround(f.height_px / 14.0))); }

}  // namespace

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

std::vector<std::string> WrapText(const std::string& line, const Font& f, int width_px,
                                  const std::string& continuation) {
  std::vector<std::string> out;
  std::string current;
  std::size_t start = 0;
  while (start <= line.size()) {
    std::size_t end = line.find(' ', start);
    if (end == std::string::npos) end = line.size();
    const std::string word = line.substr(start, end - start);
    const std::string tried = current.empty() ? word : current + " " + word;
    if (!current.empty() && TextSize(tried, f).width > width_px) {
      out.push_back(current);
      current = continuation + word;
    } else {
      current = tried;
    }
    start = end + 1;
  }
  if (!current.empty()) out.push_back(current);
  return out;
}

// Draws text with its baseline-left corner at `org`.
void PutText(cv::Mat& img, const std::string& text, cv::Point org, const Font& f, const cv::Scalar& colour) {
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
  cv::Mat patch(s.height * 2 + 4, s.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
  PutText(patch, text, {2, s.height + 2}, f);
  cv::Mat rotated;
  cv::rotate(patch, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const cv::Rect dst(centre.x - rotated.cols / 2, centre.y - rotated.rows / 2, rotated.cols, rotated.rows);
  if ((dst & cv::Rect(0, 0, img.cols, img.rows)) == dst) rotated.copyTo(img(dst));
}

}  // namespace topocal::plot
