#include "harness/harness_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <chrono>
#include <filesystem>
#include <utility>

#include "harness/harness.h"
#include "harness/harness_answer.h"
#include "harness/harness_config.h"
#include "harness/harness_report.h"
#include "util/io.h"
#include "util/shard.h"
#include "util/new_directory_guard.h"

namespace topocal::harness {
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

void WriteOutputs(const std::string& dir, const HarnessRun& run, std::ostream& out) {
  const auto answer = ComputeInverseAnswer(run);
  WriteAll(dir, RenderHarnessOutputs(run, answer));
  fmt::print(out, "{}", HarnessAnswerText(run, answer));
}

double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

void RunHarnessCommand(const HarnessRequest& a, std::ostream& out) {
  const util::NewDirectoryGuard out_guard(a.out);  // a failed run leaves no empty folder
  if (a.config.empty()) throw util::InputError("harness: --config is required (or: topocal harness merge)");
  if (a.out.empty()) throw util::InputError("harness: --out is required");
  if (a.jobs < 1) throw util::InputError(fmt::format("--jobs: must be >= 1 (got {})", a.jobs));
  const util::ShardSpec spec = a.shard.empty() ? util::ShardSpec{} : util::ParseShardSpec(a.shard);
  const auto cfg = LoadHarnessConfig(a.config);
  PrepareOutputDirectory(a.out);
  const auto t0 = std::chrono::steady_clock::now();
  const auto progress = util::StartProgress(a.progress, "cases");
  const auto run = RunHarness(cfg, spec, a.jobs, [&progress](std::size_t done, std::size_t total) {
    if (progress) progress->Update(done, total);
  });
  const double seconds = SecondsSince(t0);
  util::Log(a.log, fmt::format("{} of {} cases in {:.1f} s ({:.1f} ms per case, {} job{})", run.cases.size(),
                               run.total_cases, seconds, run.cases.empty() ? 0.0 : 1e3 * seconds / run.cases.size(),
                               a.jobs, a.jobs == 1 ? "" : "s"));
  if (a.shard.empty()) {
    WriteOutputs(a.out, run, out);
    return;
  }
  const std::string name = HarnessShardFileName(spec);
  WriteAll(a.out, {{name, HarnessShardJson(run)}});
  fmt::print(out, "shard {}/{}: {} of {} cases written to {}\n", spec.index, spec.count, run.cases.size(),
             run.total_cases, (fs::path(a.out) / name).string());
}

void RunHarnessMerge(const HarnessMergeRequest& a, std::ostream& out) {
  const util::NewDirectoryGuard out_guard(a.out);  // a failed merge leaves no empty folder
  HarnessShardMerger merger;
  for (const auto& arg : a.shards) {
    for (const auto& file : ShardFilesIn(arg)) merger.Add(util::ReadFile(file), file);
  }
  const auto run = merger.Finish();
  PrepareOutputDirectory(a.out);
  WriteOutputs(a.out, run, out);
}

}  // namespace topocal::harness
