#include "pipeline/lens_device.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <vector>

#include <Eigen/Core>
#include <fmt/format.h>

#include "calib/calibration_file.h"
#include "pipeline/detection_plane.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// A lens calibration as this mapping reads it: the pixel model, its parameter table (which were fitted) and, when
// known, the full covariance in that table's order.
struct LensSource {
  const model::CameraModel& camera;
  std::vector<std::string> names;
  std::vector<bool> fitted;
  std::optional<Eigen::MatrixXd> covariance;
  std::string method;  // the device file's calibration.method
};

// Index of `name` in `names` (the calibration's parameter table, calib::CameraParameterNames, which has every name
// asked for here).
int IndexOf(const std::vector<std::string>& names, const std::string& name) {
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw std::logic_error("lens device: the calibration has no parameter " + name);
  return static_cast<int>(it - names.begin());
}

// d(device parameter) / d(calibration parameter), rows in `device_names` order, columns in the calibration's. The
// tangential pair turns with the image orientation M as model::LensFromOpenCv turns it: (p2, p1)_mm = M^T (p2, p1).
Eigen::MatrixXd MappingJacobian(const std::vector<std::string>& device_names,
                                const std::vector<std::string>& calibration_names,
                                const model::TopographerCamera& camera) {
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(device_names.size()),
                                            static_cast<Eigen::Index>(calibration_names.size()));
  const Eigen::Matrix2d mt = camera.Orientation().transpose();
  for (int r = 0; r < static_cast<int>(device_names.size()); ++r) {
    const std::string& name = device_names[static_cast<size_t>(r)];
    if (name == "principal_point_u_px") {
      j(r, IndexOf(calibration_names, "cx")) = 1.0;
    } else if (name == "principal_point_v_px") {
      j(r, IndexOf(calibration_names, "cy")) = 1.0;
    } else if (name == "a_mm") {
      j(r, IndexOf(calibration_names, "fx")) = camera.PitchMm();
    } else if (name == "p1" || name == "p2") {  // p2_mm = (M^T q)_x, p1_mm = (M^T q)_y with q = (p2, p1)
      const int row = name == "p2" ? 0 : 1;
      j(r, IndexOf(calibration_names, "p2")) = mt(row, 0);
      j(r, IndexOf(calibration_names, "p1")) = mt(row, 1);
    } else {
      j(r, IndexOf(calibration_names, name)) = 1.0;  // a radial coefficient: the same number
    }
  }
  return j;
}

// The device parameters the calibration determines: those whose source parameter it fitted.
std::vector<std::string> DeviceNames(const LensSource& lens) {
  const auto fitted = [&](const std::string& name) {
    for (size_t i = 0; i < lens.names.size(); ++i) {
      if (lens.names[i] == name) return lens.fitted[i];
    }
    return false;
  };
  std::vector<std::string> names;
  if (fitted("cx")) names.push_back("principal_point_u_px");
  if (fitted("cy")) names.push_back("principal_point_v_px");
  if (fitted("fx")) names.push_back("a_mm");
  for (const auto name : model::LensParameterNames(lens.camera.lens)) {
    // The tangential pair turns as a pair: both are carried when either was fitted.
    const bool tangential = name == "p1" || name == "p2";
    if (fitted(std::string(name)) || (tangential && (fitted("p1") || fitted("p2")))) names.emplace_back(name);
  }
  return names;
}

bool FittedCentre(const LensSource& lens) {
  for (size_t i = 0; i < lens.names.size(); ++i) {
    if ((lens.names[i] == "ex" || lens.names[i] == "ey") && lens.fitted[i]) return true;
  }
  return false;
}

// The nominal device with the lens on its camera; the covariance block when the source has one.
model::DeviceFile LensOnDevice(const LensSource& lens, const model::Device& nominal, const std::string& name) {
  const model::CameraModel& k = lens.camera;
  if (k.width_px != nominal.camera.width_px || k.height_px != nominal.camera.height_px) {
    throw util::InputError(fmt::format("{}: calibrated at {} x {} px but the nominal device's sensor is {} x {} px",
                                       name, k.width_px, k.height_px, nominal.camera.width_px,
                                       nominal.camera.height_px));
  }
  model::TopographerCamera sensor = nominal.camera;
  sensor.principal_point_px = {k.cx_px, k.cy_px};
  const DetectionPlaneModel on_plane = DetectionPlaneModelOf(k, sensor);
  if (!on_plane.ok) throw util::InputError(fmt::format("{}: {}", name, on_plane.message));
  model::DeviceFile out;
  out.device = nominal;
  out.device.camera = on_plane.camera;
  out.device.camera.a_mm = k.fx_px * on_plane.camera.PitchMm();
  out.device.distortion = on_plane.distortion;
  if (const auto why = out.device.Invalid()) throw util::InputError(fmt::format("{}: {}", name, *why));
  if (!lens.covariance) return out;

  const std::vector<std::string> names = DeviceNames(lens);
  if (names.empty()) return out;  // nothing of the device's was fitted: no covariance to carry
  const Eigen::MatrixXd j = MappingJacobian(names, lens.names, out.device.camera);
  const Eigen::MatrixXd covariance = j * *lens.covariance * j.transpose();
  nlohmann::json matrix = nlohmann::json::array();
  for (Eigen::Index r = 0; r < covariance.rows(); ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index c = 0; c < covariance.cols(); ++c) row.push_back(covariance(r, c));
    matrix.push_back(row);
  }
  out.calibration = {{"method", lens.method},
                     {"model_error_px", on_plane.model_error_px},
                     {"covariance", {{"parameters", names}, {"matrix", matrix}}}};
  return out;
}

}  // namespace

model::DeviceFile LensCalibratedDevice(const calib::CalibrationResult& calibration, const model::Device& nominal,
                                       const std::string& calibration_name) {
  LensSource lens{calibration.camera, {}, {}, calibration.covariance, {}};
  for (const auto& p : calibration.parameters) {
    lens.names.push_back(p.name);
    lens.fitted.push_back(!p.fixed);
  }
  if (FittedCentre(lens)) {
    throw util::InputError(fmt::format("{}: a fitted distortion centre has no device parameter to carry its "
                                       "uncertainty; calibrate without --fit-centre to write a device",
                                       calibration_name));
  }
  lens.method = fmt::format(
      "lens calibration {} ({}, RMS {:.4f} px over {} corners): the screen pose is the nominal device's, not "
      "calibrated",
      calibration_name, calib::ToString(calibration.model), calibration.rms_px, calibration.corners_used);
  return LensOnDevice(lens, nominal, calibration_name);
}

MeasuringDevice LoadMeasuringDevice(const std::string& device_path, const std::string& calibration_path) {
  if (device_path.empty()) throw std::logic_error("LoadMeasuringDevice: no device");
  const model::DeviceFile file = model::LoadDevice(device_path);
  MeasuringDevice out;
  out.name = device_path;
  if (calibration_path.empty()) {
    out.device = file.device;
    out.covariance = model::DeviceCovarianceOf(file.calibration, device_path);
    if (!out.covariance) out.no_covariance = "its file has no calibration covariance: a hand-written device";
    return out;
  }
  if (!file.calibration.is_null()) {
    throw util::InputError(fmt::format("{}: a calibrated device carries its own lens (its calibration section); "
                                       "--calibration puts a lens calibration on a nominal device",
                                       device_path));
  }
  const calib::CalibrationFile cal = calib::LoadCalibrationFile(calibration_path);
  LensSource lens{cal.camera, cal.parameter_names, {}, std::nullopt, {}};
  for (const auto& n : cal.parameter_names) {
    const auto sd = cal.stddev.find(n);
    lens.fitted.push_back(sd != cal.stddev.end() && sd->second > 0);
  }
  if (!cal.covariance) {
    out.no_covariance = fmt::format("{} has no parameter covariance{}", calibration_path,
                                    cal.stddev.empty() ? "" : " (standard deviations without their correlations)");
  } else if (FittedCentre(lens)) {
    out.no_covariance = fmt::format("{} fitted its distortion centre, which no device parameter carries",
                                    calibration_path);
  } else {
    lens.covariance = cal.covariance;
    lens.method = fmt::format("lens calibration {} on the device {}", calibration_path, device_path);
  }
  const model::DeviceFile on = LensOnDevice(lens, file.device, calibration_path);
  out.device = on.device;
  if (lens.covariance && !on.calibration.is_null()) {
    out.covariance = model::DeviceCovarianceOf(on.calibration, calibration_path);
  } else if (lens.covariance) {
    out.no_covariance = fmt::format("{} fitted none of the device's parameters", calibration_path);
  }
  out.name = fmt::format("{} with the lens of {}", device_path, calibration_path);
  return out;
}

}  // namespace topocal::pipeline
