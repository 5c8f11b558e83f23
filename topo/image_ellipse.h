#pragma once
// The elliptical contour of a spot image (paper Sec. 3.1, Eq. 17, Table V): Fitzgibbon's direct fit to the spots of
// the outermost ring, which form the boundary of the pattern. See docs/paper-decisions.md for why the outer ring.
#include <optional>
#include <vector>

#include "model/ellipse_fit.h"
#include "model/null_screen.h"

namespace topocal::topo {

// Fits the contour ellipse to the spots of ring `outer_ring`; nullopt if fewer than 5 of them are present.
std::optional<model::Ellipse> FitImageContour(const std::vector<model::ImageSpot>& spots, int outer_ring);

}  // namespace topocal::topo
