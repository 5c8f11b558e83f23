// topocal calibrate: detect a planar target in a set of images and fit the camera (pipeline/calibrate_command.h).
#include <memory>

#include <fmt/format.h>

#include "calib/calibrate.h"
#include "pipeline/calibrate_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddCalibrateCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("calibrate", "Fit the camera's intrinsics and distortion to images of a target");
  auto a = std::make_shared<pipeline::CalibrateRequest>();
  cmd->add_option("--target", a->target, "Target description (Kalibr-style YAML)")->required();
  cmd->add_option("--images", a->images, "Images, a glob(3) pattern (quote it)")->required();
  cmd->add_option("--model", a->model,
                  fmt::format("Distortion model, one of {}: seidel is k1 [+ centre] (paper Eq. 18), the others "
                              "OpenCV's distCoeffs models (brown5 its default, rational8 CALIB_RATIONAL_MODEL)",
                              calib::DistortionModelNames()))
      ->capture_default_str();
  cmd->add_flag("--single-view", a->single_view,
                "One image of the target at the cornea position; needs --focal-mm, --pixel-pitch-um, --distance-mm");
  cmd->add_option("--focal-mm", a->focal_mm, "Lens focal distance, mm (single view; Seidel sigma)");
  cmd->add_option("--pixel-pitch-um", a->pixel_pitch_um, "Pixel pitch, um (single view; Seidel sigma)");
  cmd->add_option("--distance-mm", a->distance_mm, "Nominal target distance from the pinhole, mm (single view)");
  cmd->add_option("--magnification", a->magnification, "Transverse magnification M_T for the Seidel sigma")
      ->capture_default_str();
  cmd->add_option("--fix", a->fixed,
                  "Parameters to hold fixed (spaces or commas): fx fy cx cy, the model's (k1 k2 p1 p2 k3 ...), ex ey")
      ->delimiter(',');
  cmd->add_option("--fix-aspect", a->fixed_aspect_ratio,
                  "Hold fx / fy at this ratio during a multi-view fit (e.g. 1 for square pixels; 0 = free); OpenCV's "
                  "CALIB_FIX_ASPECT_RATIO")
      ->capture_default_str();
  cmd->add_flag("--fit-centre", a->fit_centre, "Fit the radial distortion centre (Seidel; brown5 needs --fix p1,p2)");
  cmd->add_option("--device", a->device, "The unit's nominal device (docs/device.md), for --device-out");
  cmd->add_option("--device-out", a->device_out,
                  "Also write the device file of this lens calibration applied to --device (its principal point, a, "
                  "pixel aspect and lens, with their covariance; the screen pose stays nominal)");
  cmd->add_flag("--robust", a->robust, "Robust loss and iterative outlier rejection");
  cmd->add_flag("--board-warp", a->board_warp,
                "Fit the target's parabolic sag with the camera (a printed board that is not flat; multi-view)");
  cmd->add_option("--loss", a->loss, "Robust loss with --robust: huber or cauchy")->capture_default_str();
  cmd->add_option("--loss-scale-px", a->loss_scale_px, "Robust loss scale, px")->capture_default_str();
  cmd->add_option("--outlier-threshold", a->outlier_threshold_sigmas, "Reject corners beyond this many robust sigmas")
      ->capture_default_str();
  cmd->add_option("--jobs", a->jobs, "Images detected at once (default: the cores available); the result does not depend on it")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  cmd->add_option("--out", a->out, "Calibration file (OpenCV FileStorage YAML)")->required();
  cmd->add_option("--json", a->json, "Also write a JSON report");
  cmd->add_option("--cross-validate", a->cross_validate_svg,
                  "Also fit two interleaved halves of the views and compare them over the image (homography "
                  "removed): the difference as a number, and its map as an SVG to this file");
  a->log = util::LogOnStderr("topocal calibrate: ");
  cmd->callback([a] { pipeline::RunCalibrate(*a, std::cout); });
}

}  // namespace topocal::tools
