#include "pipeline/target_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include "calib/target.h"
#include "calib/target_drawing.h"

namespace topocal::pipeline {

void RunTarget(const TargetRequest& request, std::ostream& out) {
  const auto description = calib::LoadTargetDescription(request.target);
  calib::WriteTargetDrawing(description, request.out, request.dpi);
  const auto paper = description.PaperExtent();
  fmt::print(out, "{}: {:.1f} x {:.1f} mm paper -> {} (print at 100 % scale)\n", description.Describe(),
             paper.WidthMm(), paper.HeightMm(), request.out);
}

}  // namespace topocal::pipeline
