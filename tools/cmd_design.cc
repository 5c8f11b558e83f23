// topocal design: the null screen's target points on the cone for the ideal image (pipeline/design_command.h).
#include <memory>

#include "pipeline/design_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddDesignCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("design", "Design the null screen: target points on the cone for the ideal image");
  auto a = std::make_shared<pipeline::DesignRequest>();
  cmd->add_option("--config", a->config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--out", a->out, "Target points CSV: ring,index,x_mm,y_mm,z_mm")->required();
  cmd->add_option("--svg", a->svg, "Also write the printable null screen (unrolled cone, 1:1) as SVG");
  auto* optimize = cmd->add_flag("--optimize", a->optimize,
                                 "Choose the rings and spots per ring for a goal (docs/screen-design.md): trade-off "
                                 "table on stdout, the chosen design written");
  cmd->add_option("--goal", a->goal, "Goal of --optimize (JSON; default: the defaults of docs/screen-design.md)")
      ->needs(optimize);
  cmd->add_option("--config-out", a->config_out, "Configuration of the chosen design (JSON), for every other verb")
      ->needs(optimize);
  cmd->add_option("--jobs", a->jobs, "Threads of --optimize (the result does not depend on it)")
      ->capture_default_str()
      ->needs(optimize);
  a->log = util::LogOnStderr("topocal design: ");
  a->progress = util::ProgressOnStderr("topocal design --optimize: ");
  cmd->callback([a] { pipeline::RunDesign(*a, std::cout); });
}

}  // namespace topocal::tools
