// topocal target: a print-ready drawing of a calibration target at physical scale.
#include <fmt/format.h>

#include "calib/target.h"
#include "calib/target_drawing.h"
#include "tools/commands.h"

namespace topocal::tools {

void AddTargetCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("target", "Draw a calibration target (checkerboard or AprilTag grid) to print");
  auto target = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto dpi = std::make_shared<double>(300.0);
  cmd->add_option("--target", *target, "Target description (Kalibr YAML: checkerboard, aprilgrid; or charuco)")->required();
  cmd->add_option("--out", *out, "Drawing: FILE.svg (mm units) or FILE.png (at --dpi)")->required();
  cmd->add_option("--dpi", *dpi, "Resolution of a PNG drawing, dots per inch")->capture_default_str();
  cmd->callback([=] {
    const auto description = calib::LoadTargetDescription(*target);
    calib::WriteTargetDrawing(description, *out, *dpi);
    const auto paper = description.PaperExtent();
    fmt::print("{}: {:.1f} x {:.1f} mm paper -> {} (print at 100 % scale)\n", description.Describe(), paper.WidthMm(),
               paper.HeightMm(), *out);
  });
}

}  // namespace topocal::tools
