// topocal export / import: the options of pipeline/export_command.h.
#include <iostream>
#include <memory>

#include "pipeline/export_command.h"
#include "tools/commands.h"

namespace topocal::tools {

void AddExportCommands(CLI::App& app) {
  auto* ex = app.add_subcommand("export", "Write a calibration or a device's camera as ROS camera_info, Kalibr "
                                          "camchain, mrcal .cameramodel or plain OpenCV YAML (docs/exchange.md)");
  auto e = std::make_shared<pipeline::ExportRequest>();
  auto* calibration = ex->add_option("--calibration", e->calibration_path, "Calibration file (topocal or OpenCV YAML)");
  ex->add_option("--device", e->device_path, "Or a device file: its camera and lens as OpenCV's K and distCoeffs")
      ->excludes(calibration);
  ex->add_option("--to", e->format, "Format: ros | kalibr | mrcal | opencv")->required();
  ex->add_option("--out", e->out_path, "Output file")->required();
  ex->add_option("--camera-name", e->camera_name, "camera_name of the ROS camera_info")->capture_default_str();
  ex->footer("Example: topocal export --calibration cal.yaml --to mrcal --out cam.cameramodel");
  ex->callback([e] { pipeline::RunExport(*e, std::cout); });

  auto* im = app.add_subcommand("import", "Read a Kalibr camchain, an OpenCV calibration YAML, an mrcal .cameramodel "
                                          "or a ROS camera_info into a calibration file every topocal verb reads "
                                          "(docs/exchange.md)");
  auto i = std::make_shared<pipeline::ImportRequest>();
  im->add_option("--from", i->format, "Format: kalibr | opencv | mrcal | ros")->required();
  im->add_option("file", i->file_path, "The file to import")->required();
  im->add_option("--camera", i->camera, "Kalibr: the camera of the camchain")->capture_default_str();
  im->add_option("--out", i->out_path, "Calibration file to write (OpenCV FileStorage YAML)")->required();
  im->footer("Example: topocal import --from mrcal cam.cameramodel --out cal.yaml");
  im->callback([i] { pipeline::RunImport(*i, std::cout); });
}

}  // namespace topocal::tools
