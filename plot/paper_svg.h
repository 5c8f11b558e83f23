#pragma once
// A print-ready black-on-white drawing at physical scale (part of the plotting layer, plot/svg.h): width and height
// in mm, the viewBox in mm, a white sheet and black rectangles, with comments that name what follows. The printable
// calibration targets (calib/target_drawing.h) are drawn with it. Output is a pure function of the calls (fixed
// 4-decimal formatting), so equal drawings give byte-identical files.
#include <string>
#include <string_view>

namespace topocal::plot {

class PaperSvg {
 public:
  // `title` goes into the header comment.
  PaperSvg(std::string_view title, double width_mm, double height_mm);

  // A black rectangle, mm from the sheet's top-left corner.
  void BlackRect(double x_mm, double y_mm, double width_mm, double height_mm);
  // An XML comment before what follows (e.g. "tag 3").
  void Comment(std::string_view text);
  // The finished document.
  std::string Finish() &&;

 private:
  std::string svg_;
};

// Text safe inside an XML comment: "--" is not allowed there and becomes "- -".
std::string XmlCommentText(std::string_view text);

}  // namespace topocal::plot
