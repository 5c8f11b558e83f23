#include "pipeline/export_command.h"

#include <fmt/format.h>

#include "calib/calibration_file.h"
#include "calib/camera_exchange.h"
#include "calib/distortion_valid_region.h"
#include "model/device.h"
#include "model/opencv_view.h"
#include "util/io.h"

namespace topocal::pipeline {

void RunExport(const ExportRequest& request, std::ostream& out) {
  const auto format = calib::ParseExportFormat(request.format);
  if (!format) throw util::InputError(fmt::format("--to: '{}' is not ros, kalibr, mrcal or opencv", request.format));
  if (request.calibration_path.empty() == request.device_path.empty()) {
    throw util::InputError("export: give one of --calibration (a calibration file) or --device (a device file)");
  }
  calib::ExportOptions options;
  options.camera_name = request.camera_name;
  if (!request.device_path.empty()) {
    // The device's camera and lens through OpenCV's view; the screen pose has no place in a camera file.
    const model::CameraModel camera = model::OpenCvView(model::LoadDevice(request.device_path).device);
    util::WriteFileAtomic(request.out_path,
                          calib::ExportCamera(camera, calib::ValidRegionOf(camera), *format, request.device_path,
                                              options));
    out << fmt::format("{} -> {} ({}: the device's camera and lens; its screen pose stays in the device file)\n",
                       request.device_path, request.out_path, request.format);
    return;
  }
  const auto cal = calib::LoadCalibrationFile(request.calibration_path);
  util::WriteFileAtomic(request.out_path, calib::ExportCalibration(cal, *format, request.calibration_path, options));
  out << fmt::format("{} -> {} ({})\n", request.calibration_path, request.out_path, request.format);
  if (!cal.camera.distortion_centre.isZero(0)) {
    out << fmt::format(
        "note: {} has a distortion centre; the export holds its closest OpenCV model "
        "(opencv_equivalent_max_error_px in the file says how close)\n",
        request.calibration_path);
  }
}

void RunImport(const ImportRequest& request, std::ostream& out) {
  util::WriteFileAtomic(request.out_path,
                        calib::ImportCalibrationText(request.format, request.file_path, request.camera));
  out << fmt::format("{} ({}) -> {}\n", request.file_path, request.format, request.out_path);
}

}  // namespace topocal::pipeline
