// topocal undistort: correct a spots CSV or an image with a calibration file (calib/calibration_file.h) or a device
// file (model/device.h).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>

#include "calib/calibration_file.h"
#include "calib/distortion_valid_region.h"
#include "correct/undistort_coverage.h"
#include "correct/undistort_map.h"
#include "correct/undistort_points.h"
#include "imageio/image_file.h"
#include "model/device.h"
#include "model/distortion.h"
#include "model/spots_csv.h"
#include "model/topographer_camera.h"
#include "pipeline/detection_plane.h"
#include "tools/commands.h"
#include "util/io.h"

namespace topocal::tools {
namespace {

struct UndistortArgs {
  std::string calibration, device, camera, spots, image, out;
};

// The camera to interpret pixels with: the given file (checked against the calibration's image size), or one
// derived from the calibration itself (principal point and focal length from its camera matrix; the pixel pitch
// is the file's when it has one, else 1 um — it cancels out for images).
model::TopographerCamera CameraFor(const UndistortArgs& a, const calib::CalibrationFile& cal) {
  if (!a.camera.empty()) {
    const auto camera = model::LoadTopographerCamera(a.camera);
    if (camera.width_px != cal.camera.width_px || camera.height_px != cal.camera.height_px) {
      throw util::InputError(fmt::format("{}: the camera is {} x {} px but the calibration {} is for {} x {} px",
                                         a.camera, camera.width_px, camera.height_px, a.calibration,
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

// The calibration on the detection plane, and the camera with its pixel aspect (fx / fy) that maps pixels to mm.
pipeline::DetectionPlaneModel OnDetectionPlane(const calib::CalibrationFile& cal, const model::TopographerCamera& sensor,
                                               const std::string& path) {
  auto on_plane = pipeline::DetectionPlaneModelOf(cal.camera, sensor);
  if (!on_plane.ok) throw util::InputError(fmt::format("{}: {}", path, on_plane.message));
  return on_plane;
}

// What corrects: the distortion on the detection plane, the camera whose pixels map onto it, and where the model is
// invertible, from a calibration file (its valid region) or from a device file (its distortion's fold within the
// sensor). `source` names the file in every message.
struct Correction {
  model::Distortion distortion;
  model::TopographerCamera camera;
  std::string source;
  double valid_radius_px = 0;     // about `valid_centre_px`, on the distorted image
  Eigen::Vector2d valid_centre_px{0, 0};
  double farthest_px = 0;         // the sensor's farthest pixel from that centre
  std::function<bool(const Eigen::Vector2d& px)> inside;
  bool has_pitch = true;          // false: a calibration that records no pixel pitch (its mm are 1 um pixels)
  const char* centre_name = "the principal point";
  const char* region_name = "valid_radius_px";
};

Correction FromCalibration(const UndistortArgs& a) {
  const auto cal = calib::LoadCalibrationFile(a.calibration);
  const auto on_plane = OnDetectionPlane(cal, CameraFor(a, cal), a.calibration);
  Correction c{on_plane.distortion, on_plane.camera, a.calibration};
  c.valid_radius_px = cal.valid_region.radius_px;
  c.valid_centre_px = {cal.camera.cx_px, cal.camera.cy_px};
  c.farthest_px = calib::FarthestSensorPixelPx(cal.camera);
  c.inside = [region = cal.valid_region, camera = cal.camera](const Eigen::Vector2d& px) {
    return calib::InsideValidRegion(region, camera, px);
  };
  c.has_pitch = !a.camera.empty() || cal.pixel_pitch_um.has_value();
  return c;
}

// A device's distortion is invertible within its fold: a distorted point closer to the centre than the fold's image
// has its one preimage inside the fold (the radial map rises monotonically up to it).
Correction FromDevice(const UndistortArgs& a) {
  if (!a.camera.empty()) throw util::InputError("--camera: not with --device (the device file holds its camera)");
  const auto device = model::LoadDevice(a.device).device;
  Correction c{device.distortion, device.camera, a.device};
  c.centre_name = "the distortion centre";
  c.region_name = "its fold";
  const Eigen::Vector2d centre_mm = model::DistortionCentreMm(c.distortion);
  const auto pixel_of = [&](const Eigen::Vector2d& mm) { return c.camera.PixelFromDetectionPlane(mm); };
  c.valid_centre_px = pixel_of(centre_mm);
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

void UndistortSpots(const UndistortArgs& a, const Correction& c) {
  if (!c.has_pitch) {
    throw util::InputError(
        fmt::format("--spots: {} has no pixel_pitch_um; give --camera to map its pixels to mm", a.calibration));
  }
  const auto rows = model::ReadSpotsCsv(a.spots);
  std::vector<Eigen::Vector2d> mm;
  for (const auto& r : rows) mm.emplace_back(r.x_mm, r.y_mm);
  const auto result = correct::UndistortPoints(c.distortion, mm);
  for (const auto& f : result.failures) {
    fmt::print(stderr, "topocal undistort: spot ({}, {}): {}\n", rows[f.index].id.ring, rows[f.index].id.index,
               f.reason);
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
    fmt::print(stderr, "topocal undistort: spot ({}, {}): at {:.0f} px from {}, beyond the {:.0f} px within which {}'s "
               "distortion model is invertible ({}): refused\n",
               rows[i].id.ring, rows[i].id.index, (px - c.valid_centre_px).norm(), c.centre_name, c.valid_radius_px,
               c.source, c.region_name);
  }
  std::vector<model::ImageSpot> out;
  for (size_t i = 0; i < rows.size(); ++i) {
    if (!result.ok[i] || !inside[i]) continue;
    model::ImageSpot s;
    s.id = rows[i].id;
    s.position_mm = result.points_mm[i];
    s.on_surface_mm.setZero();  // unknown here; not written
    out.push_back(s);
  }
  if (out.empty() && !rows.empty()) throw std::runtime_error(fmt::format("{}: no spot could be undistorted", a.spots));
  util::WriteFileAtomic(a.out, model::SpotsCsv(out));
  fmt::print("undistorted {} of {} spots ({} failed, {} beyond the valid region) -> {}\n", out.size(), rows.size(),
             result.failures.size(), outside, a.out);
}

void UndistortImageFile(const UndistortArgs& a, const Correction& c) {
  if (a.out.size() < 4 || a.out.substr(a.out.size() - 4) != ".png") {
    throw util::InputError(fmt::format("--out: {}: the output image must be a .png file", a.out));
  }
  // Read once (a missing or unreadable file is named as such, not as "not an image") and decoded from memory.
  const cv::Mat image = imageio::ReadImage(a.image, imageio::Channels::kAsStored);
  if (image.cols != c.camera.width_px || image.rows != c.camera.height_px) {
    throw util::InputError(fmt::format("{}: the image is {} x {} px but the camera is {} x {} px", a.image, image.cols,
                                       image.rows, c.camera.width_px, c.camera.height_px));
  }
  const auto map = correct::BuildUndistortMap(c.distortion, c.camera);
  const cv::Mat out = correct::UndistortImage(image, map);
  const auto coverage = correct::CoverageOf(map, c.camera);
  const auto png = imageio::EncodePng(out, a.out);
  util::WriteFileAtomic(a.out, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  fmt::print("undistorted {} x {} image -> {}\n", image.cols, image.rows, a.out);
  const auto percent = [&](int n) { return 100.0 * n / std::max(1, coverage.total_px); };
  if (coverage.beyond_fold_px > 0) {
    fmt::print(stderr,
               "topocal undistort: {:.1f} % of the output ({} px) left black: beyond the fold of {}'s distortion "
               "model, which is monotonic and invertible only within {:.0f} px of {} ({}; the sensor reaches {:.0f} "
               "px), so no unique source pixel exists there\n",
               percent(coverage.beyond_fold_px), coverage.beyond_fold_px, c.source, c.valid_radius_px, c.centre_name,
               c.region_name, c.farthest_px);
  }
  if (coverage.outside_sensor_px > 0) {
    fmt::print(stderr,
               "topocal undistort: {:.1f} % of the output ({} px) left black: they look at directions the sensor did "
               "not see (the undistorted frame keeps the sensor's size and camera matrix)\n",
               percent(coverage.outside_sensor_px), coverage.outside_sensor_px);
  }
}

void Run(const UndistortArgs& a) {
  if (a.spots.empty() == a.image.empty()) throw util::InputError("undistort: give exactly one of --spots or --image");
  if (a.calibration.empty() == a.device.empty()) {
    throw util::InputError("undistort: give exactly one of --calibration or --device");
  }
  const Correction c = a.device.empty() ? FromCalibration(a) : FromDevice(a);
  if (!a.spots.empty()) {
    UndistortSpots(a, c);
  } else {
    UndistortImageFile(a, c);
  }
}

}  // namespace

void AddUndistortCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("undistort", "Correct a spots CSV or an image with a calibration or a device file");
  auto a = std::make_shared<UndistortArgs>();
  auto* calibration = cmd->add_option("--calibration", a->calibration, "Calibration file (OpenCV FileStorage YAML)");
  cmd->add_option("--device", a->device, "Device file (JSON, docs/device.md): its camera and distortion")
      ->excludes(calibration);
  cmd->add_option("--spots", a->spots, "Spots CSV ring,index,x_mm,y_mm on the detection plane (distorted)");
  cmd->add_option("--image", a->image, "Raw image (size of the calibrated camera)");
  cmd->add_option("--out", a->out, "Output: spots CSV or .png image")->required();
  cmd->add_option("--camera", a->camera, "Topographer camera (JSON); needed for --spots unless the calibration "
                                         "records its pixel pitch");
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools
