#pragma once
// The plotting layer's SVG primitives, shared by every SVG topocal writes: the harness scatter plots
// (plot/scatter_plot.h), the QA and fleet reports' charts (plot/svg_charts.h) and the printable null screen
// (plot/null_screen_svg.h). No SVG/XML writing library is among the project's Debian dependencies (cairo draws, but
// its SVG output cannot carry ids, clip paths by name or text that a test or a browser finds), so the documents are
// written as text; the one thing that must never differ between them is how text is escaped, and it lives here.
//
// plot/ sits above model/ (the null screen's geometry) and below pipeline/ and report/, which both draw.
#include <string>
#include <string_view>

namespace topocal::plot {

// &, <, >, " and ' escaped for XML text and attributes (' as &#39;, which HTML and SVG both read).
std::string EscapeXml(std::string_view text);

}  // namespace topocal::plot
