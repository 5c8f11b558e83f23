#pragma once
// A scalar field over the cornea (power in D, height in µm) sampled on a regular grid: what topo/ computes
// (topo/map_grid.h, topo/power_map.h), plot/ draws (plot/map_image.h) and pipeline/ writes (pipeline/map_output.h).
// Held here, below both, so that the computing modules need not link the drawing ones.
//
// Frame: the topographer's (x, y) in mm, the cornea seen from the camera, x to the right and y UP on the image
// (row 0 of the grid is y_min). Sample points include the edges: x_i = x_min + i (x_max - x_min) / (nx - 1).
#include <cstddef>
#include <string>
#include <vector>

namespace topocal::model {

// NaN = no data (outside the measured zone).
struct GridMap {
  double x_min_mm = -1.0, x_max_mm = 1.0, y_min_mm = -1.0, y_max_mm = 1.0;
  int nx = 0, ny = 0;
  std::vector<double> values;  // row-major, values[j * nx + i] at (x_i, y_j), row 0 at y_min
  std::string title;           // e.g. "Axial power, sigma = 2e-4 /mm^2"
  std::string unit;            // e.g. "D" or "µm"
  double At(int i, int j) const { return values[static_cast<std::size_t>(j) * nx + i]; }
  // At least 2 x 2 samples over a finite extent, nx * ny values, none infinite; false with the reason in *why.
  bool IsValid(std::string* why) const;
};

}  // namespace topocal::model
