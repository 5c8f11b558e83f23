#pragma once
// `topocal export` and `topocal import`: a calibration to and from other tools' formats (calib/camera_exchange.h):
// ROS camera_info, Kalibr camchain, mrcal .cameramodel, plain OpenCV YAML; a device file leaves through its OpenCV
// view too.
#include <ostream>
#include <string>

namespace topocal::pipeline {

struct ExportRequest {
  std::string calibration_path;  // one of these two: a calibration file,
  std::string device_path;       // or a device file (its camera and lens, model::OpenCvView)
  std::string format;  // ros, kalibr, mrcal or opencv
  std::string out_path;
  std::string camera_name = "topocal";  // camera_name of the ROS camera_info
};

struct ImportRequest {
  std::string format;  // kalibr, opencv, mrcal or ros
  std::string file_path;
  std::string out_path;         // the calibration file to write (OpenCV FileStorage YAML)
  std::string camera = "cam0";  // Kalibr: the camera of the camchain
};

// Write the converted file and say so on `out`. util::InputError for an unknown format or a file the other format
// cannot hold.
void RunExport(const ExportRequest& request, std::ostream& out);
void RunImport(const ImportRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
