#pragma once
// `topocal target` as a library call: a print-ready drawing of a calibration target at physical scale.
#include <ostream>
#include <string>

namespace topocal::pipeline {

struct TargetRequest {
  std::string target;  // target description (Kalibr YAML: checkerboard, aprilgrid; or charuco)
  std::string out;     // FILE.svg (mm units) or FILE.png (at dpi)
  double dpi = 300.0;  // resolution of a PNG drawing, dots per inch
};

// Writes the drawing and prints the paper's size to `out`; InputError for a bad description or file name.
void RunTarget(const TargetRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
