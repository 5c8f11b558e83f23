// topocal reconstruct: the options of report/reconstruct_command.h.
#include <iostream>
#include <memory>
#include <string>

#include "report/reconstruct_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"
#include "tools/surface_option.h"

namespace topocal::tools {

void AddReconstructCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("reconstruct", "Recover the cornea from spot positions: surface, biconic fit, maps");
  auto in = std::make_shared<report::ReconstructRequest>();
  cmd->add_option("--config", in->config_path, "Topographer configuration (JSON)")->required();
  auto* spots_opt = cmd->add_option("--spots", in->spots_path, "Spots CSV (ring,index,x_mm,y_mm on the detection plane)");
  auto* image_opt = cmd->add_option("--image", in->image_path, "Raw sensor image of the spots (detected and indexed)");
  spots_opt->excludes(image_opt);
  cmd->add_option("--device", in->device_path,
                  "Device (JSON, docs/device.md) the --image was taken through: its camera, distortion, screen pose "
                  "and a (data/device.json: the nominal unit; `device calibrate` or `calibrate --device-out`: a "
                  "calibrated one)");
  cmd->add_option("--calibration", in->calibration_path,
                  "Lens calibration (YAML) put on the --device's camera, as `calibrate --device-out` would: the "
                  "--image spots are undistorted with it and its covariance carried to every U");
  cmd->add_option("--uncertainty", in->uncertainty_samples,
                  "The device's part of every U by this many seeded Monte Carlo draws of its parameters instead of "
                  "linear propagation (a cross-check)")
      ->check(CLI::Range(2, 100000))
      ->default_str("");  // not given: no draws (0 is not a value a user types)
  cmd->add_option("--seed", in->seed, "Seed of the --uncertainty draws")->capture_default_str();
  cmd->add_option("--estimator", in->estimator, "Spot centre estimator for --image: psf (default), centroid, gaussian")
      ->check(CLI::IsMember({"psf", "centroid", "gaussian"}))
      ->capture_default_str();
  cmd->add_option("--eye", in->eye, "The eye measured: OD (right) or OS (left); its maps are labelled N/T/S/I in "
                                     "the examiner's view, the JSON records it")
      ->check(CLI::IsMember({"OD", "OS"}));
  cmd->add_option("--power-scale", in->power_scale,
                  "Power maps' scale: standard (35.5-50.5 D, 1.5 D steps), extended (30-67.5 D, 2.5 D steps: "
                  "ectasia) or fit (steps of --power-step around the data)")
      ->check(CLI::IsMember({"standard", "extended", "fit"}))
      ->capture_default_str();
  cmd->add_option("--power-step", in->power_step_D, "Step of --power-scale fit, D [0.5]")->default_str("");
  cmd->add_option("--json", in->json_path, "Write the result as JSON");
  cmd->add_option("--maps", in->maps_dir,
                  "Write power and height maps (CSV + PNG) and their one-page overview (overview.png) into this "
                  "directory");
  auto overrides = std::make_shared<ReconstructionOverrides>();
  overrides->AddTo(cmd);
  cmd->add_flag("--truth", in->truth, "Compare with the configuration's cornea (pv and rms of the height difference)");
  in->override_config = [overrides](model::Config* config) { overrides->ApplyTo(config); };
  in->progress = util::ProgressOnStderr("topocal reconstruct: ");
  cmd->callback([in] {
    report::RunReconstruct(*in, std::cout);
  });
}

}  // namespace topocal::tools
