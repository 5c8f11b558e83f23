// topocal undistort: correct a spots CSV or an image with a calibration file (calib/calibration_file.h).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "calib/calibration_file.h"
#include "calib/distortion_valid_region.h"
#include "correct/undistort_coverage.h"
#include "correct/undistort_map.h"
#include "correct/undistort_points.h"
#include "imageio/image_file.h"
#include "model/spots_csv.h"
#include "model/topographer_camera.h"
#include "pipeline/detection_plane.h"
#include "tools/commands.h"
#include "util/io.h"

namespace topocal::tools {
namespace {

struct UndistortArgs {
  std::string calibration, camera, spots, image, out;
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

void Run(const UndistortArgs& a) {
  if (a.spots.empty() == a.image.empty()) throw util::InputError("undistort: give exactly one of --spots or --image");
  const auto cal = calib::LoadCalibrationFile(a.calibration);
  const auto on_plane = OnDetectionPlane(cal, CameraFor(a, cal), a.calibration);
  const auto& camera = on_plane.camera;
  const auto& distortion = on_plane.distortion;
  if (!a.spots.empty()) {
    if (a.camera.empty() && !cal.pixel_pitch_um) {
      throw util::InputError(
          fmt::format("--spots: {} has no pixel_pitch_um; give --camera to map its pixels to mm", a.calibration));
    }
    const auto rows = model::ReadSpotsCsv(a.spots);
    std::vector<Eigen::Vector2d> mm;
    for (const auto& r : rows) mm.emplace_back(r.x_mm, r.y_mm);
    const auto result = correct::UndistortPoints(distortion, mm);
    for (const auto& f : result.failures) {
      fmt::print(stderr, "topocal undistort: spot ({}, {}): {}\n", rows[f.index].id.ring, rows[f.index].id.index,
                 f.reason);
    }
    // Beyond the fold an inverse may converge, but to one of two answers: such a spot is refused, with the reason.
    size_t outside = 0;
    std::vector<bool> inside(rows.size(), true);
    for (size_t i = 0; i < rows.size(); ++i) {
      const Eigen::Vector2d px = camera.PixelFromDetectionPlane(mm[i]);
      if (calib::InsideValidRegion(cal.valid_region, cal.camera, px)) continue;
      inside[i] = false;
      if (!result.ok[i]) continue;  // already reported
      ++outside;
      fmt::print(stderr, "topocal undistort: spot ({}, {}): at {:.0f} px from the principal point, beyond the {:.0f} px "
                 "within which {}'s distortion model is invertible (valid_radius_px): refused\n",
                 rows[i].id.ring, rows[i].id.index, (px - Eigen::Vector2d(cal.camera.cx_px, cal.camera.cy_px)).norm(),
                 cal.valid_region.radius_px, a.calibration);
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
    return;
  }
  if (a.out.size() < 4 || a.out.substr(a.out.size() - 4) != ".png") {
    throw util::InputError(fmt::format("--out: {}: the output image must be a .png file", a.out));
  }
  // Read once (a missing or unreadable file is named as such, not as "not an image") and decoded from memory.
  const cv::Mat image = imageio::ReadImage(a.image, imageio::Channels::kAsStored);
  if (image.cols != camera.width_px || image.rows != camera.height_px) {
    throw util::InputError(fmt::format("{}: the image is {} x {} px but the camera is {} x {} px", a.image, image.cols,
                                       image.rows, camera.width_px, camera.height_px));
  }
  const auto map = correct::BuildUndistortMap(distortion, camera);
  const cv::Mat out = correct::UndistortImage(image, map);
  const auto coverage = correct::CoverageOf(map, camera);
  const auto png = imageio::EncodePng(out, a.out);
  util::WriteFileAtomic(a.out, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  fmt::print("undistorted {} x {} image -> {}\n", image.cols, image.rows, a.out);
  const auto percent = [&](int n) { return 100.0 * n / std::max(1, coverage.total_px); };
  if (coverage.beyond_fold_px > 0) {
    fmt::print(stderr,
               "topocal undistort: {:.1f} % of the output ({} px) left black: beyond the fold of {}'s distortion "
               "model, which is monotonic and invertible only within {:.0f} px of the principal point "
               "(valid_radius_px; the sensor reaches {:.0f} px), so no unique source pixel exists there\n",
               percent(coverage.beyond_fold_px), coverage.beyond_fold_px, a.calibration, cal.valid_region.radius_px,
               calib::FarthestSensorPixelPx(cal.camera));
  }
  if (coverage.outside_sensor_px > 0) {
    fmt::print(stderr,
               "topocal undistort: {:.1f} % of the output ({} px) left black: they look at directions the sensor did "
               "not see (the undistorted frame keeps the sensor's size and camera matrix)\n",
               percent(coverage.outside_sensor_px), coverage.outside_sensor_px);
  }
}

}  // namespace

void AddUndistortCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("undistort", "Correct a spots CSV or an image with a calibration file");
  auto a = std::make_shared<UndistortArgs>();
  cmd->add_option("--calibration", a->calibration, "Calibration file (OpenCV FileStorage YAML)")->required();
  cmd->add_option("--spots", a->spots, "Spots CSV ring,index,x_mm,y_mm on the detection plane (distorted)");
  cmd->add_option("--image", a->image, "Raw image (size of the calibrated camera)");
  cmd->add_option("--out", a->out, "Output: spots CSV or .png image")->required();
  cmd->add_option("--camera", a->camera, "Topographer camera (JSON); needed for --spots unless the calibration "
                                         "records its pixel pitch");
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools
