// topocal detect: the options of report/detect_command.h.
#include <iostream>
#include <memory>

#include "report/detect_command.h"
#include "tools/commands.h"
#include "tools/surface_option.h"

namespace topocal::tools {

void AddDetectCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("detect",
                                 "Detect, index and flag the spots of a raw image, every identity checked against the "
                                 "surface the others give (CSV + JSON summary; exit 4 and no CSV when refused)");
  auto a = std::make_shared<report::DetectRequest>();
  cmd->add_option("--image", a->image_path, "Raw sensor image of the spots")->required();
  cmd->add_option("--device", a->device_path,
                  "Device (JSON, docs/device.md) the image was taken through (data/device.json: the nominal unit)")
      ->required();
  cmd->add_option("--calibration", a->calibration_path,
                  "Lens calibration (YAML) put on the device's camera: the spots are checked undistorted, as "
                  "reconstruct --calibration measures them");
  cmd->add_option("--config", a->config_path, "Topographer configuration (JSON)")->required();
  cmd->add_option("--out", a->out_path, "Spots CSV: ring,index,x_mm,y_mm,u_px,v_px,flags (ring 0: unassigned blob)")
      ->required();
  cmd->add_option("--json", a->json_path, "Summary JSON: counts, missing identities, noise model, orientation");
  cmd->add_option("--estimator", a->estimator, "Spot centre estimator: psf (default), centroid or gaussian")
      ->check(CLI::IsMember({"psf", "centroid", "gaussian"}))
      ->capture_default_str();
  auto overrides = std::make_shared<ReconstructionOverrides>();  // the surface the identities are checked against
  overrides->AddTo(cmd);
  a->override_config = [overrides](model::Config* config) { overrides->ApplyTo(config); };
  cmd->callback([a] { report::RunDetect(*a, std::cout); });
}

}  // namespace topocal::tools
