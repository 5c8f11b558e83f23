// The sweep's stages that need OpenCV (commands.h: SweepImageStages), linked into topocal-full only.
#include <fmt/format.h>

#include "pipeline/closed_loop.h"
#include "pipeline/map_output.h"
#include "tools/commands.h"

namespace topocal::tools {
namespace {

std::vector<pipeline::ClosedLoopResult> CloseLoops(const model::Config& config, const topo::SweepResult& result,
                                                   const pipeline::ClosedLoopOptions& options) {
  std::vector<pipeline::ClosedLoopResult> corrected;
  for (const auto& row : result.rows) {
    fmt::print(stderr, "topocal sweep: closing the loop at sigma = {:.3g} ...\n", row.sigma_per_mm2);
    corrected.push_back(pipeline::RunClosedLoop(config, row.sigma_per_mm2, options));
  }
  return corrected;
}

void WriteMaps(util::StagedOutputs& outputs, const std::string& dir, const model::Config& config,
               const topo::SweepResult& result) {
  // One set: every sigma's map of a kind on the same scale, so that the sweep compares by eye.
  std::vector<pipeline::AnalysisMapEntry> entries;
  for (const auto& row : result.rows) {
    entries.push_back({fmt::format("sigma_{:+.3g}_", row.sigma_per_mm2),
                       fmt::format(", \u03c3 = {:.3g} mm\u207b\u00b2", row.sigma_per_mm2),
                       &row.analysis,
                       &config.cornea,
                       {}});
  }
  pipeline::WriteAnalysisMapSet(outputs.AddDirectory(dir), entries);
}

}  // namespace

const SweepImageStages kSweepImageStages{&CloseLoops, &WriteMaps};

}  // namespace topocal::tools
