#include "model/surface.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

namespace topocal::model {
namespace {

// Analytic derivatives against forward-mode jets: both are exact up to rounding; 1e-12 on O(1) quantities.
constexpr double kDerivativeTolerance = 1e-12;
// Analytic Hessian against central differences of the analytic gradient with h = 1e-5 mm: truncation O(h^2 S''') ~1e-10,
// rounding ~1e-16/h ~1e-11; 1e-8 is a safe bound.
constexpr double kFiniteDifferenceTolerance = 1e-8;

using Jet = ceres::Jet<double, 2>;

template <typename S>
void CheckDerivatives(const S& surface, double x, double y) {
  SurfaceDerivatives d;
  ASSERT_TRUE(surface.Evaluate(x, y, &d));
  Jet z, zx, zy;
  ASSERT_TRUE(surface.SagAndGradient(Jet(x, 0), Jet(y, 1), &z, &zx, &zy));
  EXPECT_NEAR(d.z, z.a, kDerivativeTolerance);
  EXPECT_NEAR(d.zx, z.v[0], kDerivativeTolerance);
  EXPECT_NEAR(d.zy, z.v[1], kDerivativeTolerance);
  EXPECT_NEAR(d.zx, zx.a, kDerivativeTolerance);
  EXPECT_NEAR(d.zxx, zx.v[0], kDerivativeTolerance);
  EXPECT_NEAR(d.zxy, zx.v[1], kDerivativeTolerance);
  EXPECT_NEAR(d.zxy, zy.v[0], kDerivativeTolerance);
  EXPECT_NEAR(d.zyy, zy.v[1], kDerivativeTolerance);
  const double h = 1e-5;
  SurfaceDerivatives px, mx, py, my;
  ASSERT_TRUE(surface.Evaluate(x + h, y, &px) && surface.Evaluate(x - h, y, &mx));
  ASSERT_TRUE(surface.Evaluate(x, y + h, &py) && surface.Evaluate(x, y - h, &my));
  EXPECT_NEAR(d.zx, (px.z - mx.z) / (2 * h), kFiniteDifferenceTolerance);
  EXPECT_NEAR(d.zxx, (px.zx - mx.zx) / (2 * h), kFiniteDifferenceTolerance);
  EXPECT_NEAR(d.zxy, (py.zx - my.zx) / (2 * h), kFiniteDifferenceTolerance);
  EXPECT_NEAR(d.zyy, (py.zy - my.zy) / (2 * h), kFiniteDifferenceTolerance);
}

TEST(Surface, SphereDerivatives) {
  const Sphere s{7.8, 0.0};
  for (double x : {-4.0, 0.0, 1.3, 5.0}) {
    for (double y : {-3.0, 0.0, 2.2}) CheckDerivatives(s, x, y);
  }
}

TEST(Surface, BiconicDerivatives) {
  for (const BiconicParams& p : {BiconicParams{8.35, 7.63, -0.43, -0.25, 17.0, 0, 0, 0},
                                 BiconicParams{7.2, 7.9, 0.3, -0.6, 123.0, 0.2, -0.1, 0.01}}) {
    const Biconic b{p};
    for (double x : {-4.0, 0.0, 1.3, 4.5}) {
      for (double y : {-3.0, 0.0, 2.2}) CheckDerivatives(b, x, y);
    }
  }
}

TEST(Surface, BiconicWithEqualRadiiAndNoConicIsTheSphere) {
  const Sphere s{7.8, 0.0};
  const Biconic b{BiconicParams{7.8, 7.8, 0.0, 0.0, 31.0, 0, 0, 0}};
  SurfaceDerivatives ds, db;
  for (double x : {-5.0, 0.5, 3.0}) {
    ASSERT_TRUE(s.Evaluate(x, 1.0, &ds) && b.Evaluate(x, 1.0, &db));
    EXPECT_NEAR(ds.z, db.z, 1e-14);
    EXPECT_NEAR(ds.zxx, db.zxx, 1e-13);
  }
}

TEST(Surface, RotationIsPlusAlpha) {
  // docs/paper-decisions.md: the surface is rotated by +alpha, so its x-meridian (radius rx) lies at +alpha.
  const Biconic b{BiconicParams{8.35, 7.63, 0.0, 0.0, 17.0, 0, 0, 0}};
  const double a = 17.0 * M_PI / 180.0;
  SurfaceDerivatives d;
  ASSERT_TRUE(b.Evaluate(0.0, 0.0, &d));
  // Curvature along the direction (cos a, sin a) equals 1/rx at the vertex.
  const double k_along = d.zxx * std::cos(a) * std::cos(a) + 2 * d.zxy * std::cos(a) * std::sin(a) +
                         d.zyy * std::sin(a) * std::sin(a);
  EXPECT_NEAR(k_along, 1.0 / 8.35, 1e-14);
}

TEST(Surface, UndefinedRegionIsReportedNotNaN) {
  const Biconic b{BiconicParams{7.8, 7.8, 4.5, 4.5, 0.0, 0, 0, 0}};
  EXPECT_NEAR(b.DefinedRadiusMm(), 7.8 / std::sqrt(5.5), 1e-12);
  SurfaceDerivatives d;
  EXPECT_FALSE(b.Evaluate(4.0, 0.0, &d));
  EXPECT_TRUE(b.Evaluate(3.0, 0.0, &d));
}

}  // namespace
}  // namespace topocal::model
