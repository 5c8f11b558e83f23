#include "model/surface.h"

#include <algorithm>
#include <cmath>

#include <ceres/jet.h>
#include <Eigen/Geometry>
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

// The untilted biconic's Hessian is closed-form (the tilted one comes from jets): against the jets of
// the kernel's gradient over the whole defined disc of two biconics, and its sag and gradient are the kernel's in
// double bit for bit.
TEST(Surface, UntiltedBiconicClosedFormHessianIsTheJetsToRounding) {
  // Both are exact up to rounding on curvatures of ~0.1-1 /mm: measured 2026-12-02 largest 5.6e-16 /mm,
  // regression bound 1e-14; the acceptance bound is kDerivativeTolerance.
  constexpr double kRegressionTolerance = 1e-14;
  double worst = 0;
  for (const BiconicParams& p : {BiconicParams{8.35, 7.63, -0.43, -0.25, 17.0, 0, 0, 0},
                                 BiconicParams{7.2, 7.9, 0.3, -0.6, 123.0, 0.2, -0.1, 0.01}}) {
    const Biconic b{p};
    double q[BiconicKernel::kNumParams];
    BiconicKernel::FromParams(p, q);
    const double reach = std::min(5.5, 0.99 * b.DefinedRadiusMm());
    for (int i = -20; i <= 20; ++i) {
      for (int j = -20; j <= 20; ++j) {
        const double x = reach * i / 20.0, y = reach * j / 20.0;
        if (std::hypot(x, y) > reach) continue;
        SurfaceDerivatives d;
        ASSERT_TRUE(b.Evaluate(x, y, &d));
        double z, zx, zy;
        ASSERT_TRUE(BiconicKernel::SagAndGradient(q, x, y, &z, &zx, &zy, false));
        EXPECT_EQ(d.z, z);
        EXPECT_EQ(d.zx, zx);
        EXPECT_EQ(d.zy, zy);
        Jet jz, jzx, jzy;
        ASSERT_TRUE(b.SagAndGradient(Jet(x, 0), Jet(y, 1), &jz, &jzx, &jzy));
        const double got[] = {d.zxx, d.zxy, d.zxy, d.zyy};
        const double want[] = {jzx.v[0], jzx.v[1], jzy.v[0], jzy.v[1]};
        for (int k = 0; k < 4; ++k) {
          ASSERT_NEAR(got[k], want[k], kDerivativeTolerance) << "at (" << x << ", " << y << ")";
          worst = std::max(worst, std::abs(got[k] - want[k]));
        }
      }
    }
  }
  EXPECT_LE(worst, kRegressionTolerance);
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

TEST(Surface, TiltedBiconicDerivatives) {
  // The tilted sag is a Newton root; its Hessian comes from jets through the kernel's final Newton step.
  for (const BiconicParams& p : {BiconicParams{8.35, 7.63, -0.43, -0.25, 17.0, 0.3, -0.2, 0.01, 2.0, -3.0},
                                 BiconicParams{7.2, 7.9, 0.3, -0.6, 123.0, -0.4, 0.1, 0.0, -3.0, 1.5}}) {
    const Biconic b{p};
    for (double x : {-4.0, 0.0, 1.3, 4.5}) {
      for (double y : {-3.0, 0.0, 2.2}) CheckDerivatives(b, x, y);
    }
  }
}

TEST(Surface, TiltedBiconicIsTheUntiltedOneRotatedAboutItsApex) {
  // Points of the untilted surface G, rotated by R = Ry(ty) Rx(tx) about the apex, must lie on the tilted sag,
  // and G's normal rotated by R must be the tilted sag's normal. 1e-12: the Newton root is solved to 1e-14 mm.
  constexpr double kOnSurfaceToleranceMm = 1e-12;
  BiconicParams p{8.35, 7.63, -0.43, -0.25, 17.0, 0.3, -0.2, 0.01};
  const Biconic untilted{p};
  p.tilt_x_deg = 2.5;
  p.tilt_y_deg = -3.0;
  const Biconic tilted{p};
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(p.tilt_y_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(p.tilt_x_deg * M_PI / 180.0, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d apex = untilted.ApexMm();
  SurfaceDerivatives at_apex;
  ASSERT_TRUE(untilted.Evaluate(apex.x(), apex.y(), &at_apex));
  EXPECT_NEAR(at_apex.z, apex.z(), 1e-15);
  for (double ux : {-4.0, -1.0, 0.0, 2.5, 4.5}) {
    for (double uy : {-3.5, 0.0, 1.7, 4.0}) {
      SurfaceDerivatives g, t;
      ASSERT_TRUE(untilted.Evaluate(ux, uy, &g));
      const Eigen::Vector3d q = apex + R * (Eigen::Vector3d(ux, uy, g.z) - apex);
      ASSERT_TRUE(tilted.Evaluate(q.x(), q.y(), &t));
      EXPECT_NEAR(t.z, q.z(), kOnSurfaceToleranceMm);
      const Eigen::Vector3d n = R * SurfaceNormal(g.zx, g.zy);
      EXPECT_NEAR((n - SurfaceNormal(t.zx, t.zy)).norm(), 0.0, kOnSurfaceToleranceMm);
    }
  }
  // The apex stays where it was.
  SurfaceDerivatives t;
  ASSERT_TRUE(tilted.Evaluate(apex.x(), apex.y(), &t));
  EXPECT_NEAR(t.z, apex.z(), kOnSurfaceToleranceMm);
}

TEST(Surface, ZeroTiltIsThePaperBiconicBitForBit) {
  const Biconic b{BiconicParams{8.35, 7.63, -0.43, -0.25, 17.0, 0, 0, 0}};
  double q[BiconicKernel::kNumParams];
  BiconicKernel::FromParams(b.params, q);
  double z1, zx1, zy1, z2, zx2, zy2;
  ASSERT_TRUE(b.SagAndGradient(1.3, -2.1, &z1, &zx1, &zy1));
  // The general (tilted) path at zero tilt agrees to rounding.
  ASSERT_TRUE(BiconicKernel::SagAndGradient(q, 1.3, -2.1, &z2, &zx2, &zy2, true));
  EXPECT_NEAR(z1, z2, 1e-15);
  EXPECT_NEAR(zx1, zx2, 1e-15);
  EXPECT_NEAR(zy1, zy2, 1e-15);
}

Freeform KeratoconusOnATiltedEye() {
  Freeform f;
  f.base = Biconic{BiconicParams{7.8, 7.6, -0.3, -0.1, 40.0, 0.2, -0.3, 0.0, 1.5, -2.0}};
  f.cones.push_back({25.0, 0.9, 0.8, -1.1});
  f.ablations.push_back({-4.0, 6.0, 1.0, 0.1, 0.2});
  f.zernike.push_back({3, -1, 2.0, 4.0, 0.0, 0.0});
  f.zernike.push_back({6, 2, 1.0, 4.0, 0.0, 0.0});
  return f;
}

TEST(Surface, FreeformDerivatives) {
  const Freeform f = KeratoconusOnATiltedEye();
  // Points inside the ablation zone, in its blend (r = 3.3 mm from its centre) and beyond it.
  for (double x : {-4.0, 0.0, 0.8, 3.4, 4.5}) {
    for (double y : {-3.0, -1.1, 0.2, 2.2}) CheckDerivatives(f, x, y);
  }
}

TEST(Surface, ZernikeTermsAreTheTextbookPolynomials) {
  // OSA Z(2,0) = 2 rho^2 - 1, Z(3,1) = (3 rho^3 - 2 rho) cos(theta), Z(4,-2) = (4 rho^4 - 3 rho^2) sin(2 theta).
  const double rho = 0.7, th = 0.4, R = 4.0;
  const double x = R * rho * std::cos(th), y = R * rho * std::sin(th);
  const auto value = [&](int n, int m) {
    double z = 0, zx = 0, zy = 0;
    ZernikeTerm{n, m, 1000.0, R, 0.0, 0.0}.Add(x, y, &z, &zx, &zy);  // 1000 um = 1 mm: the value itself
    return z;
  };
  EXPECT_NEAR(value(2, 0), 2 * rho * rho - 1, 1e-14);
  EXPECT_NEAR(value(3, 1), (3 * std::pow(rho, 3) - 2 * rho) * std::cos(th), 1e-14);
  EXPECT_NEAR(value(4, -2), (4 * std::pow(rho, 4) - 3 * rho * rho) * std::sin(2 * th), 1e-14);
}

TEST(Surface, AblationChangesThePowerInsideItsZoneOnly) {
  Freeform with, without;
  with.base = without.base = Biconic{BiconicParams{7.8, 7.8, 0, 0, 0, 0, 0, 0}};
  with.ablations.push_back({-4.0, 6.0, 1.0, 0.0, 0.0});
  SurfaceDerivatives a, b;
  // At 1 mm (inside the zone) the curvature changes by dc = -4 D / 337.5; beyond 4 mm the surface is unchanged
  // up to a piston.
  ASSERT_TRUE(with.Evaluate(1.0, 0.0, &a) && without.Evaluate(1.0, 0.0, &b));
  EXPECT_NEAR(a.zxx - b.zxx, -4.0 / 337.5, 1e-14);
  ASSERT_TRUE(with.Evaluate(0.0, 4.2, &a) && without.Evaluate(0.0, 4.2, &b));
  EXPECT_NEAR(a.zyy - b.zyy, 0.0, 1e-15);
  EXPECT_NEAR(a.zy - b.zy, 0.0, 1e-15);
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
