#pragma once
// Calibrations exchanged with other tools: the writers of ROS camera_info YAML, Kalibr camchain YAML, mrcal
// .cameramodel and a plain OpenCV calibration YAML (calib/camera_exchange.cc), and the readers of a Kalibr camchain,
// a ROS camera_info and an mrcal .cameramodel (calib/camera_import.cc). topocal's own file is read and written by
// calib/calibration_file.h only (also for plain OpenCV files from other tools); the writers start from what that
// reader returns. Formats, key by key, in docs/exchange.md.
//
// Every format here holds OpenCV's Brown model (fx, fy, cx, cy, k1, k2, p1, p2, k3, no distortion centre): the
// export writes CalibrationFile::opencv_camera, the closest OpenCV model when the topocal model has a centre
// (calib/opencv_equivalent.h states how close). Kalibr's radtan has no k3: exporting a camera whose k3 moves the
// image by more than kKalibrDropK3TolerancePx is refused.
#include <optional>
#include <string>

#include "calib/calibration_file.h"
#include "calib/distortion_valid_region.h"
#include "model/camera_model.h"
#include "util/io.h"

namespace topocal::calib {

enum class ExportFormat { kRos, kKalibr, kMrcal, kOpenCv };
// "ros", "kalibr", "mrcal", "opencv"; nullopt otherwise.
std::optional<ExportFormat> ParseExportFormat(const std::string& name);

// Largest shift (px, over the image border) that dropping k3 may cause in a Kalibr radtan export.
inline constexpr double kKalibrDropK3TolerancePx = 0.01;

struct ExportOptions {
  std::string camera_name = "topocal";  // ROS camera_name; Kalibr camchain key is always cam0
  std::string ros_topic = "/cam0/image_raw";  // Kalibr's rostopic
};

// The file's text in the chosen format. Throws util::InputError (naming `source`) when the format cannot hold the
// camera (Kalibr with a significant k3).
std::string ExportCalibration(const CalibrationFile& calibration, ExportFormat format, const std::string& source,
                              const ExportOptions& options = {});
// The same for any camera in OpenCV's model (no distortion centre): a calibration's opencv_camera, or a device's
// model::OpenCvView (model/opencv_view.h), with its valid region (calib/distortion_valid_region.h).
std::string ExportCamera(const model::CameraModel& camera, const DistortionValidRegion& valid_region,
                         ExportFormat format, const std::string& source, const ExportOptions& options = {});

// Individual writers (the camera must have a zero distortion centre; util::InputError otherwise).
std::string RosCameraInfoYaml(const model::CameraModel& camera, const std::string& camera_name);
std::string KalibrCamchainYaml(const model::CameraModel& camera, const std::string& ros_topic);
// With `valid_region` (when it does not cover the sensor): mrcal's valid_intrinsics_region, the circle of
// valid_radius_px about (cx, cy) as a closed 64-gon, which mrcal's tools draw and use to mask.
std::string MrcalCameraModelText(const model::CameraModel& camera, const DistortionValidRegion* valid_region = nullptr);
// A plain OpenCV calibration file (image_width, image_height, camera_matrix, distortion_coefficients) that
// cv::FileStorage, cv::undistort and LoadCalibrationFile read; `imported_from` is recorded beside them.
std::string OpenCvCalibrationText(const model::CameraModel& camera, const std::string& imported_from);

// The largest pixel shift over the image border from setting k3 (and the rational model's k4..k6) to zero: what a
// radtan export loses.
double DropK3ShiftPx(const model::CameraModel& camera);

// Reads camera `camera_key` (cam0, cam1, ...) of a Kalibr camchain YAML: camera_model pinhole, distortion_model
// radtan, intrinsics [fu fv pu pv], distortion_coeffs [k1 k2 r1 r2], resolution [w h]. Other models, missing or
// wrongly sized keys throw util::InputError "PATH: KEY: problem".
model::CameraModel ReadKalibrCamchain(const std::string& path, const std::string& camera_key = "cam0");

// The readers below refuse, with util::InputError "PATH: KEY: problem" (one line), a missing file or key, a wrongly
// sized list, a non-finite number, a focal length <= 0, an image size < 1 and a principal point outside the image
// (-0.5 ... size - 0.5 px, OpenCV's pixel convention); the camera they return is OpenCV's model (no distortion
// centre), what OpenCvCalibrationText writes.

// Reads a ROS camera_info YAML (camera_calibration_parsers, or PyYAML): image_width, image_height,
// camera_matrix {rows 3, cols 3, data [fx 0 cx 0 fy cy 0 0 1]}, distortion_model plumb_bob (5 coefficients) or
// rational_polynomial (8, k4..k6 must be 0), distortion_coefficients {rows 1, cols n, data}. The rectification and
// projection matrices are ignored: they describe a rectified stereo image, not the raw camera topocal undistorts.
model::CameraModel ReadRosCameraInfo(const std::string& path);

// Reads an mrcal .cameramodel (the Python dict literal mrcal writes and reads with ast.literal_eval): lensmodel
// LENSMODEL_OPENCV4, LENSMODEL_OPENCV5, LENSMODEL_OPENCV8 with k4..k6 = 0, or LENSMODEL_PINHOLE (no distortion);
// intrinsics [fx, fy, cx, cy, distortion...]; imagersize [w, h]. Other lens models are refused naming the model;
// extrinsics, valid_intrinsics_region and optimization_inputs are read over and ignored (topocal computes its own
// valid region).
model::CameraModel ReadMrcalCameraModel(const std::string& path);

// `topocal import`: the camera of another tool's file — `from` is "kalibr" (camera `camera_key` of a camchain),
// "opencv" (an OpenCV calibration YAML), "mrcal" or "ros" — as a plain OpenCV calibration file's text
// (OpenCvCalibrationText) that every --calibration reads. util::InputError for another `from` and what the
// readers refuse.
std::string ImportCalibrationText(const std::string& from, const std::string& path,
                                  const std::string& camera_key = "cam0");

}  // namespace topocal::calib
