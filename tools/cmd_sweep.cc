// topocal sweep: every sigma of the configuration and the paper's tables (report/sweep_command.h). Compiled into
// topocal-sweep too, which links no OpenCV and passes no image stages.
#include <memory>

#include "report/sweep_command.h"
#include "tools/cli_app.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"
#include "tools/surface_option.h"

namespace topocal::tools {

void AddSweepCommand(CLI::App& app, const SweepImageStages* image_stages) {
  auto* cmd = app.add_subcommand("sweep", "Run every sigma of the configuration and print the paper's tables");
  auto a = std::make_shared<report::SweepRequest>();
  cmd->add_option("--config", a->config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--json", a->json, "Write the sweep as JSON");
  cmd->add_option("--maps", a->maps, "Write every sigma's power, height and difference maps (CSV + PNG) here");
  auto overrides = std::make_shared<ReconstructionOverrides>();
  overrides->AddTo(cmd);
  cmd->add_flag("--correct", a->correct,
                "Close the loop for every sigma: calibrate from a rendered target, detect the spots in a rendered "
                "sensor image, undistort, reconstruct; print before and after side by side");
  cmd->add_option("--device", a->device,
                  "Sweep through this as-built device (docs/device.md): its screen pose and a image the cornea, its own "
                  "distortion replaced by each sigma; the rows are the unit uncalibrated, and its calibrated answer "
                  "is printed beside them");
  a->adjust_config = [overrides](model::Config* config) { overrides->ApplyTo(config); };
  a->image_stages = image_stages;
  a->log = util::LogOnStderr("topocal sweep: ");
  cmd->callback([a] {
    if ((a->correct || !a->maps.empty()) && !a->image_stages) throw NeedsFullCli{};  // before any work or output
    report::RunSweep(*a, std::cout);
  });
}

}  // namespace topocal::tools
