#include "topo/map_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include "util/io.h"

namespace topocal::topo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

model::GridMap ResamplePolar(const PolarField& field, int n, std::string title, std::string unit) {
  const size_t nr = field.radii_mm.size();
  if (n < 2) throw util::InputError("ResamplePolar: n must be at least 2");
  if (nr < 2 || field.meridians < 1 || field.values.size() != nr * field.meridians) {
    throw util::InputError("ResamplePolar: need >= 2 radii, >= 1 meridian and meridians * radii values");
  }
  for (size_t k = 0; k < nr; ++k) {
    if (!(field.radii_mm[k] >= 0) || (k > 0 && !(field.radii_mm[k] > field.radii_mm[k - 1]))) {
      throw util::InputError("ResamplePolar: radii must be >= 0 and strictly ascending");
    }
  }
  const double R = field.radii_mm.back();
  model::GridMap g;
  g.x_min_mm = g.y_min_mm = -R;
  g.x_max_mm = g.y_max_mm = R;
  g.nx = g.ny = n;
  g.title = std::move(title);
  g.unit = std::move(unit);
  g.values.assign(static_cast<size_t>(n) * n, kNaN);
  const auto value = [&](int m, size_t k) { return field.values[static_cast<size_t>(m) * nr + k]; };
  for (int j = 0; j < n; ++j) {
    const double y = -R + 2.0 * R * j / (n - 1);
    for (int i = 0; i < n; ++i) {
      const double x = -R + 2.0 * R * i / (n - 1);
      const double r = std::hypot(x, y);
      if (r > R * (1 + 1e-12)) continue;
      // Meridians: periodic linear interpolation in angle.
      double u = std::atan2(y, x) / (2.0 * M_PI) * field.meridians;
      if (u < 0) u += field.meridians;
      const double uf = std::floor(u);
      const double wu = u - uf;
      const int m0 = static_cast<int>(uf) % field.meridians, m1 = (m0 + 1) % field.meridians;
      // Radii: linear between the bracketing samples, the innermost sample inside the smallest radius.
      size_t k1 = std::upper_bound(field.radii_mm.begin(), field.radii_mm.end(), r) - field.radii_mm.begin();
      size_t k0 = k1 == 0 ? 0 : k1 - 1;
      k1 = std::min(k1, nr - 1);
      const double wr = k1 == k0 ? 0.0 : (r - field.radii_mm[k0]) / (field.radii_mm[k1] - field.radii_mm[k0]);
      const double v = (1 - wu) * ((1 - wr) * value(m0, k0) + wr * value(m0, k1)) +
                       wu * ((1 - wr) * value(m1, k0) + wr * value(m1, k1));
      g.values[static_cast<size_t>(j) * n + i] = v;  // NaN if a contributing sample has no data
    }
  }
  return g;
}

model::GridMap ElevationAboveSphere(const model::GridMap& sag_um, const model::Sphere& sphere) {
  std::string why;
  if (!sag_um.IsValid(&why)) throw util::InputError("GridMap: " + why);
  model::GridMap out = sag_um;
  for (int j = 0; j < sag_um.ny; ++j) {
    const double y = sag_um.y_min_mm + j * (sag_um.y_max_mm - sag_um.y_min_mm) / (sag_um.ny - 1);
    for (int i = 0; i < sag_um.nx; ++i) {
      double& v = out.values[static_cast<size_t>(j) * sag_um.nx + i];
      if (!std::isfinite(v)) continue;
      const double x = sag_um.x_min_mm + i * (sag_um.x_max_mm - sag_um.x_min_mm) / (sag_um.nx - 1);
      double sphere_z_mm, unused_zx, unused_zy;
      v = sphere.SagAndGradient(x, y, &sphere_z_mm, &unused_zx, &unused_zy) ? (sphere_z_mm - v * 1e-3) * 1e3 : kNaN;
    }
  }
  out.unit = "\u00b5m";
  return out;
}

}  // namespace topocal::topo
