#include "pipeline/undistort_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "calib/calibration_file.h"
#include "calib/distortion_valid_region.h"
#include "correct/undistort_coverage.h"
#include "correct/undistort_map.h"
#include "correct/undistort_points.h"
#include "imageio/image_file.h"
#include "model/device.h"
#include "model/spots_csv.h"
#include "pipeline/detection_plane.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

model::TopographerCamera CameraFor(const std::string& device_path, const std::string& calibration_path,
                                   const calib::CalibrationFile& cal) {
  if (!device_path.empty()) {
    const auto camera = model::LoadDevice(device_path).device.camera;
    if (camera.width_px != cal.camera.width_px || camera.height_px != cal.camera.height_px) {
      throw util::InputError(fmt::format("{}: the camera is {} x {} px but the calibration {} is for {} x {} px",
                                         device_path, camera.width_px, camera.height_px, calibration_path,
                                         cal.camera.width_px, cal.camera.height_px));
    }
    return camera;
  }
  model::TopographerCamera c;
  c.width_px = cal.camera.width_px;
  c.height_px = cal.camera.height_px;
  c.principal_point_px = {cal.camera.cx_px, cal.camera.cy_px};
  c.pixel_pitch_um = cal.pixel_pitch_um.value_or(1.0);
  c.a_mm = std::sqrt(cal.camera.fx_px * cal.camera.fy_px) * c.PitchMm();
  return c;
}

void UndistortSpots(const UndistortRequest& a, const Undistortion& c, std::ostream& out) {
  const util::LogLine& log = a.log;
  if (!c.has_pitch) {
    throw util::InputError(
        fmt::format("--spots: {} has no pixel_pitch_um; give --device to map its pixels to mm", a.calibration_path));
  }
  const auto rows = model::ReadSpotsCsv(a.spots_path);
  std::vector<Eigen::Vector2d> mm;
  for (const auto& r : rows) mm.push_back(r.position_mm);
  const auto result = correct::UndistortPoints(c.distortion, mm);
  for (const auto& f : result.failures) {
    util::Log(log, fmt::format("spot ({}, {}): {}", rows[f.index].id.ring, rows[f.index].id.index,
                            f.reason));
  }
  // Beyond the fold an inverse may converge, but to one of two answers: such a spot is refused, with the reason.
  size_t outside = 0;
  std::vector<bool> inside(rows.size(), true);
  for (size_t i = 0; i < rows.size(); ++i) {
    const Eigen::Vector2d px = c.camera.PixelFromDetectionPlane(mm[i]);
    if (c.inside(px)) continue;
    inside[i] = false;
    if (!result.ok[i]) continue;  // already reported
    ++outside;
    util::Log(log, fmt::format(
        "spot ({}, {}): at {:.0f} px from {}, beyond the {:.0f} px within which {}'s "
        "distortion model is invertible ({}): refused",
        rows[i].id.ring, rows[i].id.index, (px - c.valid_centre_px).norm(), c.centre_name, c.valid_radius_px, c.source,
        c.region_name));
  }
  std::vector<model::ImageSpot> undistorted;
  for (size_t i = 0; i < rows.size(); ++i) {
    if (!result.ok[i] || !inside[i]) continue;
    model::ImageSpot s;
    s.id = rows[i].id;
    s.position_mm = result.points_mm[i];
    s.on_surface_mm.setZero();  // unknown here; not written
    undistorted.push_back(s);
  }
  if (undistorted.empty() && !rows.empty()) {
    throw std::runtime_error(fmt::format("{}: no spot could be undistorted", a.spots_path));
  }
  util::WriteFileAtomic(a.out_path, model::SpotsCsv(undistorted));
  out << fmt::format("undistorted {} of {} spots ({} failed, {} beyond the valid region) -> {}\n", undistorted.size(),
                     rows.size(), result.failures.size(), outside, a.out_path);
}

// Why pixels of the undistorted image are black: beyond the model's fold, or looking where the sensor did not.
void SayWhatIsBlack(const correct::UndistortCoverage& coverage, const Undistortion& c, const util::LogLine& log) {
  const auto percent = [&](int n) { return 100.0 * n / std::max(1, coverage.total_px); };
  if (coverage.beyond_fold_px > 0) {
    util::Log(log, fmt::format(
        "{:.1f} % of the output ({} px) left black: beyond the fold of {}'s distortion "
        "model, which is monotonic and invertible only within {:.0f} px of {} ({}; the sensor reaches {:.0f} "
        "px), so no unique source pixel exists there",
        percent(coverage.beyond_fold_px), coverage.beyond_fold_px, c.source, c.valid_radius_px, c.centre_name,
        c.region_name, c.farthest_px));
  }
  if (coverage.outside_sensor_px > 0) {
    util::Log(log, fmt::format(
        "{:.1f} % of the output ({} px) left black: they look at directions the sensor did "
        "not see (the undistorted frame keeps the sensor's size and camera matrix)",
        percent(coverage.outside_sensor_px), coverage.outside_sensor_px));
  }
}

void UndistortImageFile(const UndistortRequest& a, const Undistortion& c, std::ostream& out) {
  if (a.out_path.size() < 4 || a.out_path.substr(a.out_path.size() - 4) != ".png") {
    throw util::InputError(fmt::format("--out: {}: the output image must be a .png file", a.out_path));
  }
  // Read once (a missing or unreadable file is named as such, not as "not an image") and decoded from memory.
  const cv::Mat image = imageio::ReadImage(a.image_path, imageio::Channels::kAsStored);
  if (image.cols != c.camera.width_px || image.rows != c.camera.height_px) {
    throw util::InputError(fmt::format("{}: the image is {} x {} px but the camera is {} x {} px", a.image_path,
                                       image.cols, image.rows, c.camera.width_px, c.camera.height_px));
  }
  const auto map = correct::BuildUndistortMap(c.distortion, c.camera);
  const cv::Mat undistorted = correct::UndistortImage(image, map);
  const auto coverage = correct::CoverageOf(map, c.camera);
  const auto png = imageio::EncodePng(undistorted, a.out_path);
  util::WriteFileAtomic(a.out_path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  out << fmt::format("undistorted {} x {} image -> {}\n", image.cols, image.rows, a.out_path);
  SayWhatIsBlack(coverage, c, a.log);
}

}  // namespace

Undistortion UndistortionFromCalibration(const std::string& calibration_path, const std::string& device_path) {
  const auto cal = calib::LoadCalibrationFile(calibration_path);
  const auto on_plane =
      CalibrationOnDetectionPlane(cal, calibration_path, CameraFor(device_path, calibration_path, cal), device_path);
  Undistortion c;
  c.distortion = on_plane.distortion;
  c.camera = on_plane.camera;
  c.source = calibration_path;
  c.valid_radius_px = cal.valid_region.radius_px;
  c.valid_centre_px = {cal.camera.cx_px, cal.camera.cy_px};
  c.farthest_px = calib::FarthestSensorPixelPx(cal.camera);
  c.inside = [region = cal.valid_region, camera = cal.camera](const Eigen::Vector2d& px) {
    return calib::InsideValidRegion(region, camera, px);
  };
  c.has_pitch = !device_path.empty() || cal.pixel_pitch_um.has_value();
  return c;
}

Undistortion UndistortionFromDevice(const std::string& device_path) {
  const auto device = model::LoadDevice(device_path).device;
  Undistortion c;
  c.distortion = device.distortion;
  c.camera = device.camera;
  c.source = device_path;
  c.centre_name = "the distortion centre";
  c.region_name = "its fold";
  const Eigen::Vector2d centre_mm = model::DistortionCentreMm(c.distortion);
  c.valid_centre_px = c.camera.PixelFromDetectionPlane(centre_mm);
  const double fold_mm = correct::SensorFoldRadiusMm(c.distortion, c.camera);
  double fold_distorted_mm = std::numeric_limits<double>::infinity();
  if (std::isfinite(fold_mm)) {
    fold_distorted_mm = (model::Distort(c.distortion, centre_mm + Eigen::Vector2d(fold_mm, 0)) - centre_mm).norm();
  }
  for (const double u : {-0.5, c.camera.width_px - 0.5}) {
    for (const double v : {-0.5, c.camera.height_px - 0.5}) {
      c.farthest_px = std::max(c.farthest_px, (Eigen::Vector2d(u, v) - c.valid_centre_px).norm());
    }
  }
  c.valid_radius_px = std::isfinite(fold_distorted_mm) ? fold_distorted_mm / c.camera.PitchMm() : c.farthest_px;
  c.inside = [camera = c.camera, centre_mm, fold_distorted_mm](const Eigen::Vector2d& px) {
    return (camera.DetectionPlaneFromPixel(px) - centre_mm).norm() < fold_distorted_mm;
  };
  return c;
}

void RunUndistort(const UndistortRequest& request, std::ostream& out) {
  if (request.spots_path.empty() == request.image_path.empty()) {
    throw util::InputError("undistort: give exactly one of --spots or --image");
  }
  if (request.calibration_path.empty() && request.device_path.empty()) {
    throw util::InputError("undistort: give --calibration (with --device for its camera) or --device");
  }
  const Undistortion c = request.calibration_path.empty()
                             ? UndistortionFromDevice(request.device_path)
                             : UndistortionFromCalibration(request.calibration_path, request.device_path);
  if (!request.spots_path.empty()) {
    UndistortSpots(request, c, out);
  } else {
    UndistortImageFile(request, c, out);
  }
}

}  // namespace topocal::pipeline
