// topocal compare: the options of pipeline/compare_command.h.
#include <iostream>
#include <memory>

#include "pipeline/compare_command.h"
#include "tools/commands.h"

namespace topocal::tools {

void AddCompareCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("compare", "Compare two measurements of one eye: each clinical number's change "
                                            "with its U, and the change maps (docs/compare.md)");
  auto a = std::make_shared<pipeline::CompareRequest>();
  cmd->add_option("a", a->a_path, "The earlier measurement (reconstruct --json)")->required();
  cmd->add_option("b", a->b_path, "The later measurement (reconstruct --json)")->required();
  cmd->add_option("--a-maps", a->a_maps_dir, "The earlier measurement's --maps directory");
  cmd->add_option("--b-maps", a->b_maps_dir, "The later measurement's --maps directory");
  cmd->add_option("--maps", a->maps_dir, "Write the change maps (CSV and PNG) into this directory");
  cmd->add_option("--json", a->json_path, "Also write the comparison as JSON");
  cmd->callback([a] {
    pipeline::RunCompare(*a, std::cout);
  });
}

}  // namespace topocal::tools
