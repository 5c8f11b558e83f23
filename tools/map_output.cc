#include "tools/map_output.h"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "model/io.h"
#include "model/surface.h"
#include "topo/map_image.h"

namespace topocal::tools {
namespace {

constexpr int kGridSide = 241;  // samples per side of the Cartesian grids (0.05 mm steps over +-6 mm)

topo::GridMap PowerGrid(const topo::PowerMaps& pm, const std::vector<double>& values, const std::string& title) {
  topo::PolarField field;
  field.meridians = pm.meridians;
  for (int k = 0; k < pm.radial_samples; ++k) field.radii_mm.push_back(pm.RhoMm(k));
  field.values = values;
  return topo::ResamplePolar(field, kGridSide, title, "D");
}

template <typename F>
topo::GridMap CartesianGrid(double radius_mm, const std::string& title, const std::string& unit, F value) {
  topo::GridMap g;
  g.x_min_mm = g.y_min_mm = -radius_mm;
  g.x_max_mm = g.y_max_mm = radius_mm;
  g.nx = g.ny = kGridSide;
  g.title = title;
  g.unit = unit;
  g.values.resize(static_cast<size_t>(kGridSide) * kGridSide);
  for (int j = 0; j < kGridSide; ++j) {
    for (int i = 0; i < kGridSide; ++i) {
      const double x = -radius_mm + 2.0 * radius_mm * i / (kGridSide - 1);
      const double y = -radius_mm + 2.0 * radius_mm * j / (kGridSide - 1);
      g.values[static_cast<size_t>(j) * kGridSide + i] = std::hypot(x, y) <= radius_mm ? value(x, y) : NAN;
    }
  }
  return g;
}

void Write(const std::string& dir, const std::string& name, const topo::GridMap& g, bool csv, int size_px) {
  const std::string base = (std::filesystem::path(dir) / name).string();
  if (csv) topo::WriteMapCsv(base + ".csv", g);
  topo::MapImageOptions o;
  o.size_px = size_px;
  topo::WriteMapPng(base + ".png", g, o);
}

}  // namespace

void WriteAnalysisMaps(const std::string& dir, const std::string& prefix, const std::string& label,
                       const topo::Analysis& a, const model::BiconicParams* truth, bool csv, int size_px) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw model::InputError(fmt::format("{}: cannot create directory: {}", dir, ec.message()));
  const auto& pm = a.power;
  Write(dir, prefix + "axial_power", PowerGrid(pm, pm.axial_D, fmt::format("Axial power{}", label)), csv, size_px);
  Write(dir, prefix + "tangential_power", PowerGrid(pm, pm.tangential_D, fmt::format("Tangential power{}", label)), csv, size_px);
  const double r = a.covered_radius_mm;
  const auto& psi = a.reconstruction.surface;
  Write(dir, prefix + "height", CartesianGrid(r, fmt::format("Height{}", label), "um", [&](double x, double y) {
          return psi.Value(x, y) * 1e3;
        }), csv, size_px);
  if (truth) {
    const model::Biconic b{*truth};
    Write(dir, prefix + "height_difference",
          CartesianGrid(r, fmt::format("Ideal - recovered height{}", label), "um", [&](double x, double y) {
            model::SurfaceDerivatives d;
            return b.Evaluate(x, y, &d) ? (d.z - psi.Value(x, y)) * 1e3 : NAN;
          }), csv, size_px);
  }
}

}  // namespace topocal::tools
