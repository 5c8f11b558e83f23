// topocal export / import: a calibration to and from other tools' formats (calib/camera_exchange.h).
#include <fmt/format.h>

#include <memory>
#include <string>

#include "calib/calibration_file.h"
#include "calib/camera_exchange.h"
#include "tools/commands.h"
#include "util/io.h"

namespace topocal::tools {
namespace {

struct ExportArgs {
  std::string calibration, to, out, camera_name = "topocal";
};

struct ImportArgs {
  std::string from, file, out, camera = "cam0";
};

void RunExport(const ExportArgs& a) {
  const auto format = calib::ParseExportFormat(a.to);
  if (!format) throw util::InputError(fmt::format("--to: '{}' is not ros, kalibr, mrcal or opencv", a.to));
  const auto cal = calib::LoadCalibrationFile(a.calibration);
  calib::ExportOptions options;
  options.camera_name = a.camera_name;
  util::WriteFileAtomic(a.out, calib::ExportCalibration(cal, *format, a.calibration, options));
  fmt::print("{} -> {} ({})\n", a.calibration, a.out, a.to);
  if (!cal.camera.distortion_centre.isZero(0)) {
    fmt::print("note: {} has a distortion centre; the export holds its closest OpenCV model "
               "(opencv_equivalent_max_error_px in the file says how close)\n", a.calibration);
  }
}

void RunImport(const ImportArgs& a) {
  util::WriteFileAtomic(a.out, calib::ImportCalibrationText(a.from, a.file, a.camera));
  fmt::print("{} ({}) -> {}\n", a.file, a.from, a.out);
}

}  // namespace

void AddExportCommands(CLI::App& app) {
  auto* ex = app.add_subcommand("export", "Write a calibration as ROS camera_info, Kalibr camchain, mrcal "
                                          ".cameramodel or plain OpenCV YAML (docs/exchange.md)");
  auto e = std::make_shared<ExportArgs>();
  ex->add_option("--calibration", e->calibration, "Calibration file (topocal or OpenCV YAML)")->required();
  ex->add_option("--to", e->to, "Format: ros | kalibr | mrcal | opencv")->required();
  ex->add_option("--out", e->out, "Output file")->required();
  ex->add_option("--camera-name", e->camera_name, "camera_name of the ROS camera_info")->capture_default_str();
  ex->footer("Example: topocal export --calibration cal.yaml --to mrcal --out cam.cameramodel");
  ex->callback([e] { RunExport(*e); });

  auto* im = app.add_subcommand("import", "Read a Kalibr camchain, an OpenCV calibration YAML, an mrcal .cameramodel "
                                          "or a ROS camera_info into a calibration file every topocal verb reads "
                                          "(docs/exchange.md)");
  auto i = std::make_shared<ImportArgs>();
  im->add_option("--from", i->from, "Format: kalibr | opencv | mrcal | ros")->required();
  im->add_option("file", i->file, "The file to import")->required();
  im->add_option("--camera", i->camera, "Kalibr: the camera of the camchain")->capture_default_str();
  im->add_option("--out", i->out, "Calibration file to write (OpenCV FileStorage YAML)")->required();
  im->footer("Example: topocal import --from mrcal cam.cameramodel --out cal.yaml");
  im->callback([i] { RunImport(*i); });
}

}  // namespace topocal::tools
