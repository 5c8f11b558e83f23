#include "topo/clinical_indices.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "model/surface.h"

namespace topocal::topo {
namespace {

ClinicalIndices Indices(const model::Surface& s, double supported_mm = 5.0) {
  const SurfaceEvaluator eval = [&](double x, double y, model::SurfaceDerivatives* d) {
    return model::EvaluateSurface(s, x, y, d);
  };
  PowerMaps maps;
  EXPECT_TRUE(ComputePowerMaps(eval, PowerMapOptions{}, &maps));
  ClinicalIndices ci;
  std::string why;
  EXPECT_TRUE(ComputeClinicalIndices(maps, eval, supported_mm, ClinicalOptions{}, &ci, &why)) << why;
  return ci;
}

TEST(ClinicalIndices, SphereHasOnePowerAndNoElevation) {
  // Axial power of a sphere is 337.5 / r everywhere; the BFS is the sphere (elevation at the fit's 1e-6 floor).
  const auto ci = Indices(model::Sphere{7.8, 0.0});
  EXPECT_NEAR(ci.steep_k_D, 337.5 / 7.8, 1e-9);
  EXPECT_NEAR(ci.flat_k_D, 337.5 / 7.8, 1e-9);
  EXPECT_NEAR(ci.kmax_D, 337.5 / 7.8, 1e-9);
  EXPECT_NEAR(ci.bfs_radius_mm, 7.8, 1e-6);
  EXPECT_LT(std::abs(ci.elevation_peak_um), 1e-3);
  EXPECT_TRUE(ci.is_available);
  EXPECT_NEAR(ci.inferior_superior_D, 0.0, 1e-9);
}

TEST(ClinicalIndices, ToricSimKFindsTheMeridians) {
  // r 7.5 / 8.0 mm (spherical meridians, k = 0), steep meridian (ry) at alpha + 90 = 120 deg: the sim-K ring
  // (0.5-1.5 mm) sees the vertex powers within 0.05 D (axial power of a toric varies slowly near the vertex).
  const auto ci = Indices(model::Biconic{model::BiconicParams{8.0, 7.5, 0.0, 0.0, 30.0, 0, 0, 0}});
  EXPECT_NEAR(ci.steep_k_D, 337.5 / 7.5, 0.05);
  EXPECT_NEAR(ci.flat_k_D, 337.5 / 8.0, 0.05);
  EXPECT_NEAR(ci.steep_axis_deg, 120.0, 1.0);
  EXPECT_NEAR(ci.flat_axis_deg, 30.0, 1.0);
  // Regression bounds: measured 2026-12-02: steep -1.4e-14 D, flat -7.1e-15 D, both axes exact (rounding: the
  // vertex powers are found on the principal meridians).
  std::printf("sim-K: steep %+.2e D, flat %+.2e D, axes %+.2e / %+.2e deg\n", ci.steep_k_D - 337.5 / 7.5,
              ci.flat_k_D - 337.5 / 8.0, ci.steep_axis_deg - 120.0, ci.flat_axis_deg - 30.0);
  EXPECT_NEAR(ci.steep_k_D, 337.5 / 7.5, 1e-9);
  EXPECT_NEAR(ci.flat_k_D, 337.5 / 8.0, 1e-9);
  EXPECT_NEAR(ci.steep_axis_deg, 120.0, 1e-6);
  EXPECT_NEAR(ci.flat_axis_deg, 30.0, 1e-6);
}

TEST(ClinicalIndices, InferiorConeShowsInIsAndKmax) {
  model::Freeform f;
  // On a sphere (constant axial power 43.27 D) an inferior protrusion steepens the cornea: I-S turns positive,
  // the elevation peak lies inferior, and Kmax rises (here at the centre: the cone's flank curves the x meridian
  // there by h exp(-y^2 / 2 sigma^2) / sigma^2 ~ +3.3 D).
  f.base = model::Biconic{model::BiconicParams{7.8, 7.8, 0.0, 0.0, 0.0, 0, 0, 0}};
  f.cones.push_back({30.0, 1.0, 0.0, -1.5});
  const auto ci = Indices(f);
  EXPECT_GT(ci.inferior_superior_D, 0.5);
  EXPECT_GT(ci.kmax_D, 337.5 / 7.8 + 1.0);
  EXPECT_GT(ci.elevation_peak_um, 5.0);
  EXPECT_LT(ci.elevation_peak_at_mm.y(), -0.5);
}

TEST(ClinicalIndices, TooLittleDataFails) {
  const model::Surface s = model::Sphere{7.8, 0.0};
  const SurfaceEvaluator eval = [&](double x, double y, model::SurfaceDerivatives* d) {
    return model::EvaluateSurface(s, x, y, d);
  };
  PowerMaps maps;
  ASSERT_TRUE(ComputePowerMaps(eval, PowerMapOptions{}, &maps));
  ClinicalIndices ci;
  std::string why;
  EXPECT_FALSE(ComputeClinicalIndices(maps, eval, 1.0, ClinicalOptions{}, &ci, &why));
  EXPECT_NE(why.find("sim-K"), std::string::npos) << why;
}

}  // namespace
}  // namespace topocal::topo
