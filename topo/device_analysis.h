#pragma once
// Reconstruction, biconic fit and maps of undistorted spots measured through an as-built device: the design's
// targets placed where the device's screen puts them, rays traced with the device's a, the vertex reference of the
// configuration (the datum of the device's calibration). Owned here so that the sweep (topo/sweep.h) and the
// measurement (pipeline/measure_spots.h) analyse through a device the same way.
#include <vector>

#include "model/config.h"
#include "model/device.h"
#include "topo/analysis.h"

namespace topocal::topo {

// Throws std::runtime_error like AnalyzeSpots.
Analysis AnalyzeThroughDevice(const std::vector<model::PlaneSpot>& spots, const model::Device& device,
                              const model::Config& config, const model::BiconicParams* truth,
                              const AnalysisOptions& options = {});

}  // namespace topocal::topo
