// topocal render-target: synthetic ground truth — a target seen through a camera with distortion, blur and noise,
// with the exact corner positions.
#include <fmt/format.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <optional>

#include "calib/calibration_file.h"
#include "calib/render_target.h"
#include "calib/target.h"
#include "imageio/image_file.h"
#include "model/camera_model.h"
#include "model/distortion.h"
#include "tools/commands.h"
#include "tools/progress.h"
#include "util/io.h"
#include "util/parallel.h"

namespace topocal::tools {
namespace {

constexpr double kUmPerMm = 1000.0;

struct RenderArgs {
  std::string target, out, truth, camera_file;
  int width_px = 640, height_px = 480;
  std::optional<double> fx_px, fy_px, cx_px, cy_px;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
  std::optional<double> sigma_per_mm2, focal_mm, pixel_pitch_um;
  double magnification = -0.065;
  std::optional<double> distance_mm;
  double tilt_x_deg = 0, tilt_y_deg = 0, roll_deg = 0, shift_x_mm = 0, shift_y_mm = 0;
  std::vector<double> rvec_deg, tvec_mm;
  calib::RenderOptions render;
};

void RequireFinite(double value, const char* option) {
  if (!std::isfinite(value)) throw util::InputError(fmt::format("{}: must be a finite number", option));
}

// An OpenCV calibration file (camera_matrix, distortion_coefficients, image_width, image_height), as written by
// `topocal calibrate` or cv::FileStorage.
model::CameraModel LoadOpenCvCamera(const std::string& path) {
  // The one calibration-file reader (calib/calibration_file.h): strict sizes, finite values, guarded parser.
  return calib::LoadCalibrationFile(path).opencv_camera;
}

model::CameraModel BuildCamera(const RenderArgs& a, const CLI::App& cmd) {
  const bool brown = cmd.count("--k1") + cmd.count("--k2") + cmd.count("--p1") + cmd.count("--p2") + cmd.count("--k3");
  const bool seidel = a.sigma_per_mm2.has_value();
  if (!a.camera_file.empty()) {
    for (const char* opt : {"--fx", "--fy", "--cx", "--cy", "--width", "--height", "--focal-mm", "--pixel-pitch-um"}) {
      if (cmd.count(opt)) throw util::InputError(fmt::format("{}: not allowed with --camera", opt));
    }
    if (brown || seidel) throw util::InputError("--camera: distortion comes from the file; drop --k1.. / --sigma");
    return LoadOpenCvCamera(a.camera_file);
  }
  model::CameraModel camera;
  camera.width_px = a.width_px;
  camera.height_px = a.height_px;
  if (camera.width_px < 1 || camera.width_px > 20000) throw util::InputError("--width: must be 1..20000 px");
  if (camera.height_px < 1 || camera.height_px > 20000) throw util::InputError("--height: must be 1..20000 px");
  if (a.focal_mm || a.pixel_pitch_um) {
    if (!(a.focal_mm && a.pixel_pitch_um)) throw util::InputError("--focal-mm and --pixel-pitch-um go together");
    if (a.fx_px || a.fy_px) throw util::InputError("--fx/--fy: not allowed with --focal-mm/--pixel-pitch-um");
    RequireFinite(*a.focal_mm, "--focal-mm");
    RequireFinite(*a.pixel_pitch_um, "--pixel-pitch-um");
    if (*a.focal_mm <= 0) throw util::InputError("--focal-mm: must be positive");
    if (*a.pixel_pitch_um <= 0) throw util::InputError("--pixel-pitch-um: must be positive");
    camera.fx_px = camera.fy_px = *a.focal_mm / (*a.pixel_pitch_um / kUmPerMm);
  } else {
    camera.fx_px = a.fx_px.value_or(600.0);
    camera.fy_px = a.fy_px.value_or(camera.fx_px);
  }
  camera.cx_px = a.cx_px.value_or(0.5 * (camera.width_px - 1));
  camera.cy_px = a.cy_px.value_or(0.5 * (camera.height_px - 1));
  for (auto [v, name] : {std::pair{camera.fx_px, "--fx"}, {camera.fy_px, "--fy"}}) {
    RequireFinite(v, name);
    if (v <= 0) throw util::InputError(fmt::format("{}: must be positive", name));
  }
  RequireFinite(camera.cx_px, "--cx");
  RequireFinite(camera.cy_px, "--cy");
  if (seidel) {
    if (brown) throw util::InputError("--sigma: not allowed with --k1/--k2/--p1/--p2/--k3");
    if (!a.focal_mm) throw util::InputError("--sigma: needs --focal-mm and --pixel-pitch-um");
    RequireFinite(*a.sigma_per_mm2, "--sigma");
    RequireFinite(a.magnification, "--magnification");
    if (a.magnification == 0) throw util::InputError("--magnification: must not be zero");
    camera.dist[0] = model::SeidelSigmaToBrownK1(*a.sigma_per_mm2, a.magnification, *a.focal_mm);
  } else {
    camera.dist = {a.k1, a.k2, a.p1, a.p2, a.k3};
    for (double k : camera.dist) RequireFinite(k, "--k1/--k2/--p1/--p2/--k3");
  }
  return camera;
}

calib::CamFromTarget BuildPose(const RenderArgs& a, const calib::TargetDescription& target) {
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

void AddRenderTargetCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "render-target", "Render a target through a camera with distortion, blur and noise (synthetic ground truth)");
  auto a = std::make_shared<RenderArgs>();
  cmd->add_option("--target", a->target, "Target description (Kalibr YAML)")->required();
  cmd->add_option("--out", a->out, "Rendered 8-bit grey image (PNG)")->required();
  cmd->add_option("--truth", a->truth, "Exact corner positions, CSV id,x_px,y_px (OpenCV pixel convention)");
  auto* g_cam = cmd->add_option_group("camera", "Pinhole camera (OpenCV intrinsics) or a calibration file");
  g_cam->add_option("--camera", a->camera_file, "OpenCV calibration YAML (camera_matrix, distortion_coefficients, "
                                                "image_width, image_height)");
  g_cam->add_option("--width", a->width_px, "Image width, px")->capture_default_str();
  g_cam->add_option("--height", a->height_px, "Image height, px")->capture_default_str();
  g_cam->add_option("--fx", a->fx_px, "Focal length x, px [600]");
  g_cam->add_option("--fy", a->fy_px, "Focal length y, px [= fx]");
  g_cam->add_option("--cx", a->cx_px, "Principal point x, px [(width - 1) / 2]");
  g_cam->add_option("--cy", a->cy_px, "Principal point y, px [(height - 1) / 2]");
  g_cam->add_option("--focal-mm", a->focal_mm, "Focal length, mm (with --pixel-pitch-um instead of --fx/--fy)");
  g_cam->add_option("--pixel-pitch-um", a->pixel_pitch_um, "Pixel pitch, um");
  auto* g_dist = cmd->add_option_group("distortion", "Brown-Conrady (OpenCV) coefficients or a Seidel sigma");
  g_dist->add_option("--k1", a->k1, "Radial k1");
  g_dist->add_option("--k2", a->k2, "Radial k2");
  g_dist->add_option("--p1", a->p1, "Tangential p1");
  g_dist->add_option("--p2", a->p2, "Tangential p2");
  g_dist->add_option("--k3", a->k3, "Radial k3");
  g_dist->add_option("--sigma", a->sigma_per_mm2,
                     "Seidel sigma, mm^-2 (paper Eq. 18; needs --focal-mm, --pixel-pitch-um; k1 = sigma f^2 / M_T^3)");
  g_dist->add_option("--magnification", a->magnification, "Transverse magnification M_T for --sigma")
      ->capture_default_str();
  auto* g_pose = cmd->add_option_group("pose", "Where the target is: facing the camera, or an explicit pose");
  g_pose->add_option("--distance-mm", a->distance_mm, "Target centre on the optical axis at this distance, mm");
  g_pose->add_option("--tilt-x-deg", a->tilt_x_deg, "Target turned about its x axis, degrees");
  g_pose->add_option("--tilt-y-deg", a->tilt_y_deg, "Then about its y axis, degrees");
  g_pose->add_option("--roll-deg", a->roll_deg, "Then about the optical axis, degrees");
  g_pose->add_option("--shift-x-mm", a->shift_x_mm, "Then shifted across the view, mm");
  g_pose->add_option("--shift-y-mm", a->shift_y_mm, "Then shifted across the view, mm");
  g_pose->add_option("--rvec-deg", a->rvec_deg, "cam_from_target rotation vector, degrees (3 numbers)")
      ->expected(3)->delimiter(',');
  g_pose->add_option("--tvec-mm", a->tvec_mm, "cam_from_target translation, mm (3 numbers)")
      ->expected(3)->delimiter(',');
  auto* g_render = cmd->add_option_group("rendering", "Sampling, blur and noise");
  g_render->add_option("--supersampling", a->render.supersampling, "N: ~N*N sub-samples per edge pixel")
      ->capture_default_str();
  g_render->add_option("--blur-px", a->render.blur_sigma_px, "Optical Gaussian blur sigma, px")->capture_default_str();
  g_render->add_option("--noise", a->render.noise_grey, "Gaussian noise sigma, grey levels")->capture_default_str();
  g_render->add_option("--seed", a->render.seed, "Random seed (sub-sample offsets, noise)")->capture_default_str();
  a->render.jobs = util::AvailableCores();
  g_render->add_option("--jobs", a->render.jobs, "Threads (the image does not depend on it; default: the cores available)")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  g_render->add_option("--black", a->render.black_grey, "Grey level of the ink")->capture_default_str();
  g_render->add_option("--white", a->render.white_grey, "Grey level of the paper")->capture_default_str();
  g_render->add_option("--background", a->render.background_grey, "Grey level beyond the paper")
      ->capture_default_str();
  cmd->callback([a, cmd] {
    const auto target = calib::LoadTargetDescription(a->target);
    const model::CameraModel camera = BuildCamera(*a, *cmd);
    const calib::CamFromTarget pose = BuildPose(*a, target);
    std::string why;
    if (!a->render.IsValid(&why)) throw util::InputError(fmt::format("rendering options: {}", why));
    const auto view = [&] {
      const Progress progress(fmt::format("topocal render-target: rendering {} x {}", camera.width_px, camera.height_px));
      return calib::RenderTarget(target, camera, pose, a->render, &why);
    }();
    if (!view) throw util::InputError(fmt::format("cannot render: {}", why));
    const auto png = imageio::EncodePng(view->image, a->out);
    // Both files are written only once everything has been computed; each atomically.
    const std::string truth = calib::CornerTruthCsv(*view);
    util::StagedOutputs outputs;  // published together or not at all
    outputs.AddFile(a->out, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
    if (!a->truth.empty()) outputs.AddFile(a->truth, truth);
    outputs.Commit();
    fmt::print("{} seen at {}x{} px: {}/{} corners in view -> {}{}\n", target.Describe(), camera.width_px,
               camera.height_px, view->corners.size(), target.CornerIds().size(), a->out,
               a->truth.empty() ? "" : ", truth -> " + a->truth);
  });
}

}  // namespace topocal::tools
