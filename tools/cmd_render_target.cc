// topocal render-target: synthetic ground truth — a target seen through a camera with distortion, blur and noise,
// with the exact corner positions (pipeline/render_target_command.h).
#include <memory>

#include "pipeline/render_target_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddRenderTargetCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "render-target", "Render a target through a camera with distortion, blur and noise (synthetic ground truth)");
  auto a = std::make_shared<pipeline::RenderTargetRequest>();
  cmd->add_option("--target", a->target, "Target description (Kalibr YAML)")->required();
  cmd->add_option("--out", a->out, "Rendered 8-bit grey image (PNG)")->required();
  cmd->add_option("--truth", a->truth, "Exact corner positions, CSV id,x_px,y_px (OpenCV pixel convention)");
  auto* g_cam = cmd->add_option_group("camera", "Pinhole camera (OpenCV intrinsics) or a calibration file");
  g_cam->add_option("--camera", a->camera_file, "OpenCV calibration YAML (camera_matrix, distortion_coefficients, "
                                                "image_width, image_height)");
  g_cam->add_option("--width", a->width_px, "Image width, px")->default_str("640");
  g_cam->add_option("--height", a->height_px, "Image height, px")->default_str("480");
  g_cam->add_option("--fx", a->fx_px, "Focal length x, px [600]");
  g_cam->add_option("--fy", a->fy_px, "Focal length y, px [= fx]");
  g_cam->add_option("--cx", a->cx_px, "Principal point x, px [(width - 1) / 2]");
  g_cam->add_option("--cy", a->cy_px, "Principal point y, px [(height - 1) / 2]");
  g_cam->add_option("--focal-mm", a->focal_mm, "Focal length, mm (with --pixel-pitch-um instead of --fx/--fy)");
  g_cam->add_option("--pixel-pitch-um", a->pixel_pitch_um, "Pixel pitch, um");
  auto* g_dist = cmd->add_option_group("distortion", "Brown-Conrady (OpenCV) coefficients or a Seidel sigma");
  g_dist->add_option("--k1", a->k1, "Radial k1")->default_str("0");
  g_dist->add_option("--k2", a->k2, "Radial k2")->default_str("0");
  g_dist->add_option("--p1", a->p1, "Tangential p1")->default_str("0");
  g_dist->add_option("--p2", a->p2, "Tangential p2")->default_str("0");
  g_dist->add_option("--k3", a->k3, "Radial k3")->default_str("0");
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
  g_render->add_option("--jobs", a->render.jobs, "Threads (the image does not depend on it; default: the cores available)")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  g_render->add_option("--black", a->render.black_grey, "Grey level of the ink")->capture_default_str();
  g_render->add_option("--white", a->render.white_grey, "Grey level of the paper")->capture_default_str();
  g_render->add_option("--background", a->render.background_grey, "Grey level beyond the paper")
      ->capture_default_str();
  a->progress = util::ProgressOnStderr("topocal render-target: ");
  cmd->callback([a] { pipeline::RunRenderTarget(*a, std::cout); });
}

}  // namespace topocal::tools
