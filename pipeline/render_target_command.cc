#include "pipeline/render_target_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <cmath>
#include <string_view>
#include <utility>

#include "calib/calibration_file.h"
#include "calib/target.h"
#include "imageio/image_file.h"
#include "model/camera_model.h"
#include "model/distortion.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

constexpr double kUmPerMm = 1000.0;
constexpr int kDefaultWidthPx = 640, kDefaultHeightPx = 480;
constexpr double kDefaultFocalPx = 600.0;

void RequireFinite(double value, const char* option) {
  if (!std::isfinite(value)) throw util::InputError(fmt::format("{}: must be a finite number", option));
}

bool BrownGiven(const RenderTargetRequest& a) { return a.k1 || a.k2 || a.p1 || a.p2 || a.k3; }

// An OpenCV calibration file (camera_matrix, distortion_coefficients, image_width, image_height), as written by
// `topocal calibrate` or cv::FileStorage; no intrinsics or distortion may be given beside it.
model::CameraModel CameraFromFile(const RenderTargetRequest& a) {
  for (auto [given, opt] : {std::pair{a.fx_px.has_value(), "--fx"}, {a.fy_px.has_value(), "--fy"},
                            {a.cx_px.has_value(), "--cx"}, {a.cy_px.has_value(), "--cy"},
                            {a.width_px.has_value(), "--width"}, {a.height_px.has_value(), "--height"},
                            {a.focal_mm.has_value(), "--focal-mm"}, {a.pixel_pitch_um.has_value(), "--pixel-pitch-um"}}) {
    if (given) throw util::InputError(fmt::format("{}: not allowed with --camera", opt));
  }
  if (BrownGiven(a) || a.sigma_per_mm2) {
    throw util::InputError("--camera: distortion comes from the file; drop --k1.. / --sigma");
  }
  // The one calibration-file reader (calib/calibration_file.h): strict sizes, finite values, guarded parser.
  return calib::LoadCalibrationFile(a.camera_file).opencv_camera;
}

// The pinhole's focal lengths, from pixels or from the lens and the pixel pitch.
void SetFocalLengths(const RenderTargetRequest& a, model::CameraModel* camera) {
  if (a.focal_mm || a.pixel_pitch_um) {
    if (!(a.focal_mm && a.pixel_pitch_um)) throw util::InputError("--focal-mm and --pixel-pitch-um go together");
    if (a.fx_px || a.fy_px) throw util::InputError("--fx/--fy: not allowed with --focal-mm/--pixel-pitch-um");
    RequireFinite(*a.focal_mm, "--focal-mm");
    RequireFinite(*a.pixel_pitch_um, "--pixel-pitch-um");
    if (*a.focal_mm <= 0) throw util::InputError("--focal-mm: must be positive");
    if (*a.pixel_pitch_um <= 0) throw util::InputError("--pixel-pitch-um: must be positive");
    camera->fx_px = camera->fy_px = *a.focal_mm / (*a.pixel_pitch_um / kUmPerMm);
  } else {
    camera->fx_px = a.fx_px.value_or(kDefaultFocalPx);
    camera->fy_px = a.fy_px.value_or(camera->fx_px);
  }
}

void SetDistortion(const RenderTargetRequest& a, model::CameraModel* camera) {
  if (a.sigma_per_mm2) {
    if (BrownGiven(a)) throw util::InputError("--sigma: not allowed with --k1/--k2/--p1/--p2/--k3");
    if (!a.focal_mm) throw util::InputError("--sigma: needs --focal-mm and --pixel-pitch-um");
    RequireFinite(*a.sigma_per_mm2, "--sigma");
    RequireFinite(a.magnification, "--magnification");
    if (a.magnification == 0) throw util::InputError("--magnification: must not be zero");
    camera->dist[0] = model::SeidelSigmaToBrownK1(*a.sigma_per_mm2, a.magnification, *a.focal_mm);
  } else {
    camera->dist = {a.k1.value_or(0), a.k2.value_or(0), a.p1.value_or(0), a.p2.value_or(0), a.k3.value_or(0)};
    for (double k : camera->dist) RequireFinite(k, "--k1/--k2/--p1/--p2/--k3");
  }
}

model::CameraModel BuildCamera(const RenderTargetRequest& a) {
  if (!a.camera_file.empty()) return CameraFromFile(a);
  model::CameraModel camera;
  camera.width_px = a.width_px.value_or(kDefaultWidthPx);
  camera.height_px = a.height_px.value_or(kDefaultHeightPx);
  if (camera.width_px < 1 || camera.width_px > 20000) throw util::InputError("--width: must be 1..20000 px");
  if (camera.height_px < 1 || camera.height_px > 20000) throw util::InputError("--height: must be 1..20000 px");
  SetFocalLengths(a, &camera);
  camera.cx_px = a.cx_px.value_or(0.5 * (camera.width_px - 1));
  camera.cy_px = a.cy_px.value_or(0.5 * (camera.height_px - 1));
  for (auto [v, name] : {std::pair{camera.fx_px, "--fx"}, {camera.fy_px, "--fy"}}) {
    RequireFinite(v, name);
    if (v <= 0) throw util::InputError(fmt::format("{}: must be positive", name));
  }
  RequireFinite(camera.cx_px, "--cx");
  RequireFinite(camera.cy_px, "--cy");
  SetDistortion(a, &camera);
  return camera;
}

calib::CamFromTarget BuildPose(const RenderTargetRequest& a, const calib::TargetDescription& target) {
  const bool explicit_pose = !a.rvec_deg.empty() || !a.tvec_mm.empty();
  if (explicit_pose) {
    if (a.distance_mm) throw util::InputError("--rvec-deg/--tvec-mm: not allowed with --distance-mm");
    if (a.rvec_deg.size() != 3 || a.tvec_mm.size() != 3) {
      throw util::InputError("--rvec-deg and --tvec-mm: both needed, three numbers each");
    }
    for (double v : a.rvec_deg) RequireFinite(v, "--rvec-deg");
    for (double v : a.tvec_mm) RequireFinite(v, "--tvec-mm");
    return calib::PoseFromRotationVector(Eigen::Vector3d(a.rvec_deg[0], a.rvec_deg[1], a.rvec_deg[2]),
                                         Eigen::Vector3d(a.tvec_mm[0], a.tvec_mm[1], a.tvec_mm[2]));
  }
  if (!a.distance_mm) throw util::InputError("--distance-mm (or --rvec-deg with --tvec-mm): pose is required");
  RequireFinite(*a.distance_mm, "--distance-mm");
  if (*a.distance_mm <= 0) throw util::InputError("--distance-mm: must be positive");
  for (auto [v, name] : {std::pair{a.tilt_x_deg, "--tilt-x-deg"}, {a.tilt_y_deg, "--tilt-y-deg"},
                         {a.roll_deg, "--roll-deg"}, {a.shift_x_mm, "--shift-x-mm"}, {a.shift_y_mm, "--shift-y-mm"}}) {
    RequireFinite(v, name);
  }
  if (std::abs(a.tilt_x_deg) >= 89 || std::abs(a.tilt_y_deg) >= 89) {
    throw util::InputError("--tilt-x-deg/--tilt-y-deg: must be within +-89 degrees");
  }
  return calib::PoseFacingTarget(target, *a.distance_mm, a.tilt_x_deg, a.tilt_y_deg, a.roll_deg, a.shift_x_mm,
                                 a.shift_y_mm);
}

}  // namespace

void RunRenderTarget(const RenderTargetRequest& a, std::ostream& out) {
  const auto target = calib::LoadTargetDescription(a.target);
  const model::CameraModel camera = BuildCamera(a);
  const calib::CamFromTarget pose = BuildPose(a, target);
  std::string why;
  if (!a.render.IsValid(&why)) throw util::InputError(fmt::format("rendering options: {}", why));
  const auto view = [&] {
    const auto progress =
        util::StartProgress(a.progress, fmt::format("rendering {} x {}", camera.width_px, camera.height_px));
    return calib::RenderTarget(target, camera, pose, a.render, &why);
  }();
  if (!view) throw util::InputError(fmt::format("cannot render: {}", why));
  const auto png = imageio::EncodePng(view->image, a.out);
  // Both files are written only once everything has been computed; each atomically.
  const std::string truth = calib::CornerTruthCsv(*view);
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  if (!a.truth.empty()) outputs.AddFile(a.truth, truth);
  outputs.Commit();
  fmt::print(out, "{} seen at {}x{} px: {}/{} corners in view -> {}{}\n", target.Describe(), camera.width_px,
             camera.height_px, view->corners.size(), target.CornerIds().size(), a.out,
             a.truth.empty() ? "" : ", truth -> " + a.truth);
}

}  // namespace topocal::pipeline
