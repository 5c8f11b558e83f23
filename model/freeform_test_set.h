#pragma once
// topocal's own test set of corneas: keratoconus cones, myopic and hyperopic ablations,
// irregular astigmatism and biconics over the clinical range, each with its apex off the axis and the eye tilted.
// Every entry is a model::Freeform; the forward model images any of them (model/null_screen.h). Each is focused
// on the instrument axis (model::FocusOnAxis: z(0, 0) = 0), as the topographer positions an eye.
#include <string>
#include <vector>

#include "model/surface.h"
#include "util/io.h"

namespace topocal::model {

struct TestCornea {
  std::string name;
  std::string kind;  // "keratoconus", "ablation", "irregular", "biconic"
  Freeform surface;
};

// The whole set (benchmarked; docs/reconstruction.md gives its table).
std::vector<TestCornea> FreeformTestSet();
// The named entries of the set (for the CI tests: a handful of representative corneas). Throws
// util::InputError naming an unknown entry.
std::vector<TestCornea> FreeformTestSubset(const std::vector<std::string>& names);

}  // namespace topocal::model
