// topocal simulate: the options of pipeline/simulate_command.h.
#include <iostream>
#include <memory>

#include "pipeline/simulate_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddSimulateCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("simulate", "Synthesise the (distorted) spot image of the configured cornea");
  auto a = std::make_shared<pipeline::SimulateRequest>();
  cmd->add_option("--config", a->config_path, "Topographer configuration (JSON)")->required();
  auto* sigma =
      cmd->add_option("--sigma", a->sigma_per_mm2, "Seidel distortion coefficient sigma, mm^-2 (paper Eq. 18)");
  auto* device = cmd->add_option("--device", a->device_path,
                                 "As-built device (JSON, docs/device.md): its screen pose, a and distortion");
  sigma->excludes(device);
  cmd->add_option("--sphere-radius-mm", a->sphere_radius_mm,
                  "With --device: image a reference ball of this radius instead of the configured cornea, mm");
  cmd->add_option("--ball-at", a->ball_at_mm, "Vertex of the reference ball: x y z, mm (default 0 0 0)")->expected(3);
  cmd->add_option("--out", a->out_path, "Spots CSV on the detection plane (distorted): ring,index,x_mm,y_mm")
      ->required();
  a->log = util::LogOnStderr("topocal simulate: ");
  cmd->callback([a] { pipeline::RunSimulate(*a, std::cout); });
}

}  // namespace topocal::tools
