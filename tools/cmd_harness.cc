// topocal harness: the residual-distortion sweep and its inverse answer (harness/harness_command.h; docs/harness.md).
//   topocal harness --config H.json --out DIR [--shard i/N] [--jobs J]
//   topocal harness merge --out DIR SHARD...
#include <memory>

#include "harness/harness_command.h"
#include "tools/commands.h"
#include "util/terminal_progress.h"

namespace topocal::tools {

void AddHarnessCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "harness", "Sweep distortion x corneas x noise x calibration error; tables, plots and the largest residual "
                 "distortion within clinical limits (docs/harness.md)");
  auto a = std::make_shared<harness::HarnessRequest>();
  cmd->add_option("--config", a->config, "Harness configuration (JSON, docs/harness.md)");
  cmd->add_option("--out", a->out, "Output directory (created if missing)");
  cmd->add_option("--shard", a->shard,
                  "Run only shard i of N (cases with index % N == i) and write DIR/shard-<i>-of-<N>.json for merge");
  cmd->add_option("--jobs", a->jobs, "Threads in this process (the results do not depend on it; default: the cores available)")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  a->progress = util::ProgressOnStderr("topocal harness: ");
  a->log = util::LogOnStderr("topocal harness: ");

  auto* merge = cmd->add_subcommand("merge", "Merge the shard files of one configuration into the outputs of a "
                                             "single run");
  auto m = std::make_shared<harness::HarnessMergeRequest>();
  merge->add_option("--out", m->out, "Output directory (created if missing)")->required();
  merge->add_option("shards", m->shards, "Shard files, or directories holding shard-<i>-of-<N>.json files")->required();
  merge->callback([m] {
    harness::RunHarnessMerge(*m, std::cout);
  });

  cmd->callback([a, merge] {
    if (merge->parsed()) return;
    harness::RunHarnessCommand(*a, std::cout);
  });
}

}  // namespace topocal::tools
