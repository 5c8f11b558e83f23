// The sweep's stages that need OpenCV (commands.h: SweepImageStages), linked into topocal-full only.
#include "pipeline/sweep_image_stages.h"
#include "tools/commands.h"

namespace topocal::tools {

const SweepImageStages kSweepImageStages{&pipeline::CloseSweepLoops, &pipeline::WriteSweepMaps};

}  // namespace topocal::tools
