// topocal target: a print-ready drawing of a calibration target at physical scale (pipeline/target_command.h).
#include <memory>

#include "pipeline/target_command.h"
#include "tools/commands.h"

namespace topocal::tools {

void AddTargetCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("target", "Draw a calibration target (checkerboard or AprilTag grid) to print");
  auto a = std::make_shared<pipeline::TargetRequest>();
  cmd->add_option("--target", a->target, "Target description (Kalibr YAML: checkerboard, aprilgrid; or charuco)")->required();
  cmd->add_option("--out", a->out, "Drawing: FILE.svg (mm units) or FILE.png (at --dpi)")->required();
  cmd->add_option("--dpi", a->dpi, "Resolution of a PNG drawing, dots per inch")->capture_default_str();
  cmd->callback([a] { pipeline::RunTarget(*a, std::cout); });
}

}  // namespace topocal::tools
