#pragma once
// The calibration file: OpenCV FileStorage YAML that cv::FileStorage loads and cv::undistort uses as it is, with
// topocal's own fields beside OpenCV's.
//
//   %YAML:1.0
//   ---
//   calibration_tool: topocal              # absent in plain OpenCV files, which LoadCalibrationFile also accepts
//   tool_version: "0.1.0"
//   calibration_date: "2026-11-25T16:40:00Z"
//   model: seidel | brown5 | rational8       # calib::DistortionModelNames
//   single_view: 0 | 1
//   image_width: 1600                      # px
//   image_height: 1200
//   camera_matrix: !!opencv-matrix         # 3x3 [fx 0 cx; 0 fy cy; 0 0 1], px
//   distortion_coefficients: !!opencv-matrix   # 1x5 k1 k2 p1 p2 k3, or 1x8 with k4 k5 k6 (OpenCV order)
//   distortion_centre: !!opencv-matrix     # 1x2 e (normalised units) of the topocal model; [0 0] = OpenCV's model
//   # only when e != 0: the exact topocal model; camera_matrix / distortion_coefficients then hold the closest
//   # OpenCV model (calib/opencv_equivalent.h), opencv_equivalent_max_error_px says how close over the image.
//   topocal_camera_matrix, topocal_distortion_coefficients, opencv_equivalent_max_error_px
//   parameter_names: [fx, fy, cx, cy, k1, k2, p1, p2, k3, ex, ey]   # calib::CameraParameterNames of the model
//   parameter_values / parameter_stddev: 1xN (stddev 0 = fixed)
//   parameter_covariance: NxN, same order (rows/columns of fixed parameters zero)
//   rms_px, per_view_rms_px (sequence), views_used, images (sequence), outliers (count)
//   seidel_sigma_per_mm2, seidel_sigma_stddev_per_mm2, magnification   # Seidel with a known focal length in mm
//   focal_mm, pixel_pitch_um               # whenever known (given, or fitted f_px x pitch)
//   target_distance_mm                     # single view: the fitted distance of the target origin
//   target                                 # the target description file
//   valid_radius_px, valid_region_covers_sensor   # where the distortion model is monotonic and invertible
//                                          # (calib/distortion_valid_region.h); optional on read: computed if absent
#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "calib/distortion_valid_region.h"
#include "model/camera_model.h"
#include "util/io.h"

namespace topocal::calib {

struct CalibrationProvenance {
  std::string target_path;
  std::vector<std::string> image_paths;  // parallel to the views given to the calibration
  std::string date_utc;                  // ISO 8601; empty = now
};

struct CalibrationFile {
  model::CameraModel camera;         // the exact model (with its distortion centre)
  model::CameraModel opencv_camera;  // camera_matrix + distortion_coefficients as OpenCV reads them
  bool written_by_topocal = false;
  std::string model = "brown5";
  bool single_view = false;
  std::optional<double> rms_px;
  std::vector<double> per_view_rms_px;
  std::map<std::string, double> stddev;  // by parameter name
  std::vector<std::string> parameter_names;
  std::optional<Eigen::MatrixXd> covariance;  // parameter_names order; absent in older files
  std::optional<double> sigma_per_mm2, sigma_stddev_per_mm2, magnification, focal_mm, pixel_pitch_um;
  std::string target, date, tool_version;
  // Of `camera`: as stored (topocal files since 0.1.0), else computed when the file is read.
  DistortionValidRegion valid_region;
};

// The YAML text for a successful result. Throws util::InputError for a failed result and std::runtime_error
// when the OpenCV-equivalent model cannot be computed.
std::string CalibrationFileText(const CalibrationResult& result, const CalibrationProvenance& provenance);
// Writes it atomically (util::WriteFileAtomic). Throws util::InputError if the path cannot be written.
void WriteCalibrationFile(const std::string& path, const CalibrationResult& result,
                          const CalibrationProvenance& provenance);

// Reads a topocal or plain OpenCV calibration file. Strict: a missing key, a wrongly sized or non-finite matrix,
// or a file that is not a calibration throws util::InputError "PATH: KEY: problem".
CalibrationFile LoadCalibrationFile(const std::string& path);
// The same from the file's text; `path` names it in errors (calib/file_storage.h guards the parser).
CalibrationFile ParseCalibrationFile(const std::string& text, const std::string& path);

// The parameters' covariance in parameter_names order: the stored one (full = true) or, for a file without it,
// the diagonal of the standard deviations (full = false: correlations unknown).
struct ParameterCovariance {
  std::vector<std::string> names;
  Eigen::MatrixXd matrix;
  bool full = false;
};
ParameterCovariance ParameterCovarianceOf(const CalibrationFile& file);

// The --json report: rms_px, camera_matrix, dist_coeffs, stddev, views_used, per_view_rms_px, outliers, and more.
std::string CalibrationReportJson(const CalibrationResult& result, const CalibrationProvenance& provenance);

}  // namespace topocal::calib
