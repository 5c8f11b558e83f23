// topocal harness: the residual-distortion sweep and its inverse answer (docs/harness.md).
//   topocal harness --config H.json --out DIR [--shard i/N] [--jobs J]
//   topocal harness merge --out DIR SHARD...
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "harness/harness.h"
#include "harness/harness_answer.h"
#include "harness/harness_config.h"
#include "harness/harness_report.h"
#include "model/config.h"
#include "tools/commands.h"
#include "tools/output_dir.h"
#include "tools/progress.h"
#include "util/io.h"
#include "util/parallel.h"

namespace topocal::tools {
namespace {

namespace fs = std::filesystem;

void PrepareOutputDirectory(const std::string& dir) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    throw util::InputError(fmt::format("{}: --out: exists and is not a directory", dir));
  }
  // Created with the outputs (util::StagedOutputs), so that an interrupted run leaves no empty directory.
}

// Stages every file, then publishes them together: a failed or interrupted run leaves no partial set of outputs.
void WriteAll(const std::string& dir, const std::vector<std::pair<std::string, std::string>>& files) {
  util::StagedOutputs outputs;
  const fs::path staging = outputs.AddDirectory(dir);  // DIR is created only when the outputs are published
  for (const auto& [name, content] : files) util::WriteFileAtomic((staging / name).string(), content);
  outputs.Commit();
}

void WriteOutputs(const std::string& dir, const harness::HarnessRun& run) {
  const auto answer = harness::ComputeInverseAnswer(run);
  WriteAll(dir, harness::RenderHarnessOutputs(run, answer));
  fmt::print("{}", harness::HarnessAnswerText(run, answer));
}

double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

void AddHarnessCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "harness", "Sweep distortion x corneas x noise x calibration error; tables, plots and the largest residual "
                 "distortion within clinical limits (docs/harness.md)");
  auto config = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto shard = std::make_shared<std::string>();
  auto jobs = std::make_shared<int>(util::AvailableCores());
  cmd->add_option("--config", *config, "Harness configuration (JSON, docs/harness.md)");
  cmd->add_option("--out", *out, "Output directory (created if missing)");
  cmd->add_option("--shard", *shard,
                  "Run only shard i of N (cases with index % N == i) and write DIR/shard-<i>-of-<N>.json for merge");
  cmd->add_option("--jobs", *jobs, "Threads in this process (the results do not depend on it; default: the cores available)")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));

  auto* merge = cmd->add_subcommand("merge", "Merge the shard files of one configuration into the outputs of a "
                                             "single run");
  auto merge_out = std::make_shared<std::string>();
  auto inputs = std::make_shared<std::vector<std::string>>();
  merge->add_option("--out", *merge_out, "Output directory (created if missing)")->required();
  merge->add_option("shards", *inputs, "Shard files, or directories holding shard-<i>-of-<N>.json files")->required();
  merge->callback([=] {
    const NewDirectoryGuard out_guard(*merge_out);  // a failed merge leaves no empty folder
    // One shard at a time: memory holds the merged cases and one shard file, whatever the number of shards.
    harness::HarnessShardMerger merger;
    for (const auto& arg : *inputs) {
      for (const auto& file : harness::ShardFilesIn(arg)) merger.Add(util::ReadFile(file), file);
    }
    const auto run = merger.Finish();
    PrepareOutputDirectory(*merge_out);
    WriteOutputs(*merge_out, run);
  });

  cmd->callback([=] {
    if (merge->parsed()) return;
    if (config->empty()) throw util::InputError("harness: --config is required (or: topocal harness merge)");
    if (out->empty()) throw util::InputError("harness: --out is required");
    const NewDirectoryGuard out_guard(*out);  // a failed run leaves no empty folder
    if (*jobs < 1) throw util::InputError(fmt::format("--jobs: must be >= 1 (got {})", *jobs));
    const util::ShardSpec spec = shard->empty() ? util::ShardSpec{} : util::ParseShardSpec(*shard);
    const auto cfg = harness::LoadHarnessConfig(*config);
    PrepareOutputDirectory(*out);
    const auto t0 = std::chrono::steady_clock::now();
    Progress progress("topocal harness: cases");
    const auto run = harness::RunHarness(
        cfg, spec, *jobs, [&progress](std::size_t done, std::size_t total) { progress.Update(done, total); });
    const double seconds = SecondsSince(t0);
    fmt::print(stderr, "topocal harness: {} of {} cases in {:.1f} s ({:.1f} ms per case, {} job{})\n",
               run.cases.size(), run.total_cases, seconds, run.cases.empty() ? 0.0 : 1e3 * seconds / run.cases.size(),
               *jobs, *jobs == 1 ? "" : "s");
    if (shard->empty()) {
      WriteOutputs(*out, run);
      return;
    }
    const std::string name = harness::HarnessShardFileName(spec);
    WriteAll(*out, {{name, harness::HarnessShardJson(run)}});
    fmt::print("shard {}/{}: {} of {} cases written to {}\n", spec.index, spec.count, run.cases.size(),
               run.total_cases, (fs::path(*out) / name).string());
  });
}

}  // namespace topocal::tools
