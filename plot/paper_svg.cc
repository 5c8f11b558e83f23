#include "plot/paper_svg.h"

#include <fmt/format.h>

namespace topocal::plot {

std::string XmlCommentText(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    if (c == '-' && !out.empty() && out.back() == '-') out += ' ';
    out += c;
  }
  if (!out.empty() && out.back() == '-') out += ' ';  // "-->" would end the comment early
  return out;
}

PaperSvg::PaperSvg(std::string_view title, double width_mm, double height_mm) {
  svg_ = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<!-- {} -->\n"
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.4f}mm\" height=\"{:.4f}mm\" viewBox=\"0 0 {:.4f} {:.4f}\" "
      "shape-rendering=\"crispEdges\">\n"
      "<rect x=\"0\" y=\"0\" width=\"{:.4f}\" height=\"{:.4f}\" fill=\"#ffffff\"/>\n<g fill=\"#000000\">\n",
      XmlCommentText(title), width_mm, height_mm, width_mm, height_mm, width_mm, height_mm);
}

void PaperSvg::BlackRect(double x_mm, double y_mm, double width_mm, double height_mm) {
  svg_ += fmt::format("<rect x=\"{:.4f}\" y=\"{:.4f}\" width=\"{:.4f}\" height=\"{:.4f}\"/>\n", x_mm, y_mm, width_mm,
                      height_mm);
}

void PaperSvg::Comment(std::string_view text) { svg_ += fmt::format("<!-- {} -->\n", XmlCommentText(text)); }

std::string PaperSvg::Finish() && {
  svg_ += "</g>\n</svg>\n";
  return std::move(svg_);
}

}  // namespace topocal::plot
