#include "pipeline/sweep_image_stages.h"

#include <fmt/format.h>

#include "pipeline/map_output.h"

namespace topocal::pipeline {

std::vector<ClosedLoopResult> CloseSweepLoops(const model::Config& config, const topo::SweepResult& result,
                                              const ClosedLoopOptions& options, const util::LogLine& log) {
  std::vector<ClosedLoopResult> corrected;
  for (const auto& row : result.rows) {
    util::Log(log, fmt::format("closing the loop at sigma = {:.3g} ...", row.sigma_per_mm2));
    corrected.push_back(RunClosedLoop(config, row.sigma_per_mm2, options));
  }
  return corrected;
}

void WriteSweepMaps(util::StagedOutputs& outputs, const std::string& dir, const model::Config& config,
                    const topo::SweepResult& result) {
  std::vector<AnalysisMapEntry> entries;
  for (const auto& row : result.rows) {
    entries.push_back({fmt::format("sigma_{:+.3g}_", row.sigma_per_mm2),
                       fmt::format(", \u03c3 = {:.3g} mm\u207b\u00b2", row.sigma_per_mm2),
                       &row.analysis,
                       &config.cornea,
                       {}});
  }
  WriteAnalysisMapSet(outputs.AddDirectory(dir), entries);
}

}  // namespace topocal::pipeline
