#pragma once
// The surface a simulation images (simulate, render-spots): the configuration's cornea, or a reference ball of a
// given radius with its vertex near the cornea position; and the check that a simulated Seidel sigma leaves the
// configuration's image unfolded. The messages name the command line's options (--sphere-radius-mm, --ball-at,
// --sigma), the requests' fields of the same meaning.
#include <string>
#include <vector>

#include "model/config.h"
#include "model/surface.h"

namespace topocal::pipeline {

// sphere_radius_mm 0: the configuration's cornea; otherwise a ball of that radius with its vertex at ball_at_mm
// (x, y, z; empty: the origin). Throws util::InputError naming the option for a non-physical radius, a vertex
// without a radius, or a vertex more than 5 mm from the cornea position.
model::Surface SurfaceToImage(const model::Config& config, double sphere_radius_mm, const std::vector<double>& ball_at_mm);

// Throws util::InputError when the Seidel sigma folds the configuration's image (|sigma| at or beyond
// model::MaxFoldFreeSigmaPerMm2; 1e308 wrote rows of -inf).
void RequireFoldFreeSigma(double sigma_per_mm2, const model::Config& config, const std::string& config_path);

}  // namespace topocal::pipeline
