// topocal undistort: the options of pipeline/undistort_command.h.
#include <iostream>
#include <memory>

#include "pipeline/undistort_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddUndistortCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("undistort", "Correct a spots CSV or an image with a calibration or a device file");
  auto a = std::make_shared<pipeline::UndistortRequest>();
  cmd->add_option("--calibration", a->calibration_path, "Calibration file (OpenCV FileStorage YAML)");
  cmd->add_option("--device", a->device_path,
                  "Device file (JSON, docs/device.md): its camera and distortion; with --calibration only its camera "
                  "(pixel pitch, orientation: needed for --spots unless the calibration records its pitch)");
  cmd->add_option("--spots", a->spots_path, "Spots CSV ring,index,x_mm,y_mm on the detection plane (distorted)");
  cmd->add_option("--image", a->image_path, "Raw image (size of the calibrated camera)");
  cmd->add_option("--out", a->out_path, "Output: spots CSV or .png image")->required();
  a->log = util::LogOnStderr("topocal undistort: ");
  cmd->callback([a] { pipeline::RunUndistort(*a, std::cout); });
}

}  // namespace topocal::tools
