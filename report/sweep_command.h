#pragma once
// `topocal sweep` as a library call: every sigma of the configuration through the model, the paper's tables
// (V, VI, VII) and the clinical indices, optionally through an as-built device, closed through a calibration
// (--correct) and written as JSON and map images. The stages that need OpenCV are function pointers
// (SweepImageStages) so that a program linking no OpenCV (topocal-sweep) runs everything else from this library.
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "model/config.h"
#include "pipeline/closed_loop.h"
#include "topo/sweep.h"
#include "util/io.h"
#include "util/progress_display.h"

namespace topocal::report {

// The sweep's two stages that need OpenCV: closing the loop at every sigma (a rendered target and sensor image,
// calibrated, detected, undistorted) and the map images (pipeline/sweep_image_stages.h).
struct SweepImageStages {
  std::vector<pipeline::ClosedLoopResult> (*close_loops)(const model::Config& config, const topo::SweepResult& result,
                                                         const pipeline::ClosedLoopOptions& options,
                                                         const util::LogLine& log);
  void (*write_maps)(util::StagedOutputs& outputs, const std::string& dir, const model::Config& config,
                     const topo::SweepResult& result);
};

struct SweepRequest {
  std::string config;  // topographer configuration (JSON)
  std::string json;    // the sweep as JSON, when not empty
  std::string maps;    // every sigma's power, height and difference maps (CSV + PNG) in this directory; needs stages
  bool correct = false;  // close the loop at every sigma; needs stages
  std::string device;    // sweep through this as-built device (JSON); not with correct
  // Changes to the loaded configuration before the sweep (the command line's reconstruction overrides).
  std::function<void(model::Config*)> adjust_config;
  const SweepImageStages* image_stages = nullptr;  // null: correct and maps cannot run
  util::LogLine log;                               // spots not imaged, each loop being closed
};

// Prints the tables to `out` and writes the JSON and the maps together or not at all. InputError for options that
// do not go together or a bad file; std::logic_error when correct or maps is asked without image_stages.
void RunSweep(const SweepRequest& request, std::ostream& out);

}  // namespace topocal::report
