#pragma once
// The sweep's stages that need OpenCV (report/sweep_command.h's SweepImageStages): closing the loop at every sigma
// and the map images. Only a program that links OpenCV (topocal-full) hands them to the sweep.
#include <string>
#include <vector>

#include "model/config.h"
#include "pipeline/closed_loop.h"
#include "topo/sweep.h"
#include "util/io.h"
#include "util/progress_display.h"

namespace topocal::pipeline {

// One closed loop (pipeline/closed_loop.h) per row of the sweep, in its order; each start is logged.
std::vector<ClosedLoopResult> CloseSweepLoops(const model::Config& config, const topo::SweepResult& result,
                                              const ClosedLoopOptions& options, const util::LogLine& log);

// Every sigma's maps into `dir`, staged in `outputs`: one set, every map of a kind on the same scale, so that the
// sweep compares by eye.
void WriteSweepMaps(util::StagedOutputs& outputs, const std::string& dir, const model::Config& config,
                    const topo::SweepResult& result);

}  // namespace topocal::pipeline
