#pragma once
// Text on the map images (plot/map_image.cc): DejaVu Sans through OpenCV's FreeType module so that µ, ², °, σ and −
// print as themselves, OpenCV's ASCII Hershey font with a transliteration where the font file is missing.
#include <string>
#include <vector>
#include <string_view>

#include <opencv2/core.hpp>

namespace topocal::plot {

struct Font {
  int height_px;  // em height
};

// The few non-ASCII symbols of our titles and units in ASCII ("µ" kept as the marker \x01, drawn as a u with a
// descender).
std::string Transliterate(std::string_view s);
cv::Size TextSize(const std::string& text, const Font& f);
// `line` broken at spaces into lines no wider than `width_px` in `f` (a word wider than that stands on its own line);
// every line after the first begins with `continuation`.
std::vector<std::string> WrapText(const std::string& line, const Font& f, int width_px,
                                  const std::string& continuation = "");
// `org` is the left end of the baseline.
void PutText(cv::Mat& img, const std::string& text, cv::Point org, const Font& f,
             const cv::Scalar& colour = cv::Scalar(0, 0, 0));
void PutCentred(cv::Mat& img, const std::string& text, cv::Point centre_baseline, const Font& f);
void PutRightMiddle(cv::Mat& img, const std::string& text, cv::Point right_middle, const Font& f);
void PutLeftMiddle(cv::Mat& img, const std::string& text, cv::Point left_middle, const Font& f);
// Rotated by 90 degrees counter-clockwise (reads upwards), centred on `centre`.
void PutVertical(cv::Mat& img, const std::string& text, cv::Point centre, const Font& f);

}  // namespace topocal::plot
