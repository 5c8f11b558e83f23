#pragma once
// Round numbers for the maps' axes, colour bars and scales (plot/map_image.cc, plot/map_scale.cc).
#include <vector>

namespace topocal::plot {

// A round step (1, 2 or 5 times a power of ten) of at least range / target_count.
double NiceStep(double range, double target_count);
// The multiples of `step` in [lo, hi] (at most a thousand; else the two ends).
std::vector<double> Ticks(double lo, double hi, double step);
// lo + k step up to hi: the band boundaries of a stepped scale (at most a thousand; else the two ends).
std::vector<double> StepTicks(double lo, double hi, double step);
// Decimals that print every multiple of `step` exactly (1.5 -> 1, 0.25 -> 2, 5 -> 0).
int Decimals(double step);

}  // namespace topocal::plot
