#pragma once
// The data grids of maps (docs/maps.md): a polar field resampled onto the Cartesian grid the maps are drawn from, and
// the elevation above a sphere. The grid type is model/grid_map.h; topo computes the values,
// plot/map_image.h draws them and pipeline/map_output.h writes the files.
#include <string>
#include <vector>

#include "model/surface.h"
#include "model/grid_map.h"
#include "util/io.h"

namespace topocal::topo {

// A field on a polar grid: `meridians` equally spaced meridians (meridian m at angle 2 pi m / meridians from +x
// towards +y) times samples at the ascending radii `radii_mm` (r = 0 allowed).
struct PolarField {
  std::vector<double> radii_mm;
  int meridians = 0;
  std::vector<double> values;  // values[m * radii_mm.size() + k]; NaN = no data
};

// Resamples a polar field onto an n x n grid over [-R, R]^2, R = the largest radius: bilinear in (r, angle),
// periodic in angle; NaN beyond R; inside the smallest radius the innermost ring's value on that meridian.
// Throws util::InputError on an inconsistent field or n < 2.
model::GridMap ResamplePolar(const PolarField& field, int n, std::string title, std::string unit);

// Elevation above a sphere (the best-fit sphere of the clinical indices, topo/clinical_indices.h, fitted by
// topo/sphere_fit.h — this only evaluates it), um: sphere sag - surface sag, positive where the surface stands in
// front of the sphere (towards the camera), the clinical sign. `sag_um` is the surface's sag in um (z into the eye,
// as topo/ heights); the sphere's cap facing the camera is used. Samples beyond the sphere's equator and no-data
// samples have no data. Keeps the grid and sets the unit to "µm"; the title is the caller's.
model::GridMap ElevationAboveSphere(const model::GridMap& sag_um, const model::Sphere& sphere);

}  // namespace topocal::topo
