// topocal device calibrate: the whole device (screen pose, principal point, a, distortion) from reference-ball images
// (pipeline/device_command.h).
#include <memory>

#include "pipeline/device_command.h"
#include "tools/commands.h"

namespace topocal::tools {

void AddDeviceCommand(CLI::App& app) {
  auto* device = app.add_subcommand("device", "Calibrate the whole device (screen pose, camera, distortion)");
  device->require_subcommand(1);
  auto* cmd = device->add_subcommand(
      "calibrate",
      "Fit the null screen's pose, the principal point, a and the distortion from reference-ball images");
  auto a = std::make_shared<pipeline::DeviceCalibrateRequest>();
  cmd->add_option("--config", a->config, "Topographer design (JSON)")->required();
  cmd->add_option("--device", a->nominal_device,
                  "Nominal device file (JSON, docs/device.md): the starting point and priors' centre")
      ->required();
  cmd->add_option("--balls", a->balls, "Raw images of the reference balls (space separated)")->required();
  cmd->add_option("--radii-mm", a->ball_radii_mm, "Certified radius of each ball, in the order of --balls, mm")
      ->required();
  cmd->add_option("--target", a->target, "Target description (YAML) of the --targets views");
  cmd->add_option("--targets", a->targets,
                  "Views of the target through the same camera, a glob(3) pattern (quote it): their corners join "
                  "the fit, so every lens coefficient (p1, p2, k3, ...) is fitted with the screen pose");
  cmd->add_option("--corner-sigma-px", a->options.corner_sigma_px, "Noise of one target corner per axis, px")
      ->capture_default_str();
  cmd->add_option("--out", a->out, "Calibrated device file (JSON)")->required();
  auto* datum =
      cmd->add_option("--datum", a->datum_ball_number, "The ball whose vertex defines z = 0 (the axial gauge), 1-based")
          ->capture_default_str();
  cmd->add_option("--ball-steps-mm", a->options.ball_steps_mm,
                  "The alternative axial gauge: each ball's known position along the axis (a stage's readings, mm, "
                  "in the order of --balls; only differences matter): no ball is assumed at the working position")
      ->excludes(datum);
  cmd->add_option("--spot-sigma-px", a->options.spot_sigma_px, "Noise of one spot centre per axis, px")
      ->capture_default_str();
  cmd->add_option("--tol-tilt-deg", a->options.priors.tilt_deg, "Prior: screen tilt tolerance (1 sigma), deg")
      ->capture_default_str();
  cmd->add_option("--tol-roll-deg", a->options.priors.roll_deg, "Prior: screen roll tolerance, deg")->capture_default_str();
  cmd->add_option("--tol-lateral-mm", a->options.priors.lateral_mm, "Prior: screen decentration tolerance, mm")
      ->capture_default_str();
  cmd->add_option("--tol-axial-mm", a->options.priors.axial_mm, "Prior: screen axial position tolerance, mm")
      ->capture_default_str();
  cmd->add_option("--tol-principal-point-mm", a->options.priors.principal_point_mm,
                  "Prior: principal point tolerance on the sensor, mm")
      ->capture_default_str();
  cmd->add_option("--tol-a-relative", a->options.priors.a_relative, "Prior: relative tolerance of a")
      ->capture_default_str();
  cmd->add_flag("--fit-radial-scale", a->options.fit_radial_scale,
                "Also fit the screen's radial scale (cone-angle or print-scale error)");
  cmd->add_option("--max-chi2-per-dof", a->options.max_chi2_per_dof,
                  "Above this chi2/dof the model is flagged as not describing the images (exit 3)")
      ->capture_default_str();
  cmd->add_flag("--quiet", a->quiet, "Print nothing but errors");
  cmd->callback([a] { pipeline::RunDeviceCalibrate(*a, std::cout); });
}

}  // namespace topocal::tools
