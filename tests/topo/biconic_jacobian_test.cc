#include "topo/biconic_jacobian.h"

#include <random>

#include <ceres/jet.h>
#include <fmt/format.h>
#include <gtest/gtest.h>

namespace topocal::topo {
namespace {

using K = model::BiconicKernel;
using Jet = ceres::Jet<double, K::kNumParams>;

// Parameter vectors: the paper cornea, an eye off the axis and tilted, and a prolate/oblate mix at a large alpha.
std::vector<std::array<double, K::kNumParams>> Cases() {
  std::vector<std::array<double, K::kNumParams>> cases;
  for (const model::BiconicParams& p : {model::BiconicParams{8.35, 7.63, -0.43, -0.25, 17.0, 0, 0, 0},
                                        model::BiconicParams{8.35, 7.63, -0.43, -0.25, 17.0, 0.3, -0.4, 0.002, 2.0, -2.2},
                                        model::BiconicParams{7.9, 7.2, -0.6, 0.3, 123.0, -0.45, 0.2, -0.001, -3.0, 0.5}}) {
    std::array<double, K::kNumParams> q;
    K::FromParams(p, q.data());
    cases.push_back(q);
  }
  return cases;
}

// Points over a 4.5 mm disc (the paper's reconstructed zone).
std::vector<Eigen::Vector2d> Points() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector2d> pts;
  while (pts.size() < 200) {
    const Eigen::Vector2d p(u(rng), u(rng));
    if (p.norm() <= 1.0) pts.push_back(4.5 * p);
  }
  return pts;
}

TEST(BiconicJacobian, AgreesWithCeresJetsOfTheKernel) {
  // Jets carry the kernel's own derivatives: the closed form agrees to rounding. Measured max 4.3e-16 (relative to
  // the largest derivative of the point) on 2026-12-01, hence the regression bound 5e-15. Acceptance 1e-8: a
  // Jacobian error that small does not change where the fit converges, because the optimum depends only on the
  // residual. It can only slow the convergence down.
  constexpr double kAcceptance = 1e-8;
  constexpr double kRegression = 5e-15;
  double worst = 0;
  for (const auto& q : Cases()) {
    for (const bool tilted : {false, true}) {
      const BiconicSagJacobian surface(q.data(), tilted);
      Jet qj[K::kNumParams];
      for (int i = 0; i < K::kNumParams; ++i) qj[i] = Jet(q[i], i);
      for (const auto& p : Points()) {
        double z, dz[K::kNumParams];
        Jet zj;
        const bool ok_jet = K::Sag(qj, Jet(p.x()), Jet(p.y()), &zj, tilted);
        ASSERT_EQ(surface.Evaluate(p.x(), p.y(), &z, dz), ok_jet);
        if (!ok_jet) continue;
        EXPECT_NEAR(z, zj.a, 1e-14);
        const double scale = std::max(1.0, zj.v.cwiseAbs().maxCoeff());
        for (int j = 0; j < K::kNumParams; ++j) worst = std::max(worst, std::abs(dz[j] - zj.v[j]) / scale);
      }
    }
  }
  RecordProperty("worst", fmt::format("{:.3g}", worst));
  EXPECT_LT(worst, kAcceptance);
  EXPECT_LT(worst, kRegression);
}

TEST(BiconicJacobian, SagIsTheKernelsBitForBit) {
  // The fit's residual is the surface the simulation renders: the same double, tilted or not.
  int compared = 0;
  for (const auto& q : Cases()) {
    for (const bool tilted : {false, true}) {
      const BiconicSagJacobian surface(q.data(), tilted);
      for (const auto& p : Points()) {
        double z = 0, z_kernel = 0;
        const bool ok = surface.Sag(p.x(), p.y(), &z);
        ASSERT_EQ(ok, K::Sag(q.data(), p.x(), p.y(), &z_kernel, tilted));
        if (!ok) continue;
        EXPECT_EQ(z, z_kernel);
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 6 * 200);
}

TEST(BiconicJacobian, SagNearIsTheRootToRounding) {
  // The fit's warm root (BiconicSagJacobian::SagNear) from the sag at parameters moved as by one of Ceres' steps,
  // small (1e-9: near the optimum) or large (1e-3: the first steps), and from 0.05 mm off: the same root as Sag's
  // to rounding: F = u_z - G is a difference of terms of ~1 mm, so its root is defined to a few ulps only, and
  // the last bits depend on the start. Measured max 1.3e-15 mm on 2026-12-02: regression bound 3e-15; acceptance
  // 1e-13 mm, far below the fits' residuals (~1e-3 mm) and their 1e-12 relative cost tolerance.
  constexpr double kAcceptanceMm = 1e-13;
  constexpr double kRegressionMm = 3e-15;
  double worst = 0;
  int compared = 0;
  for (const auto& q : Cases()) {
    const BiconicSagJacobian surface(q.data(), true);
    for (const double move : {1e-9, 1e-3}) {
      auto moved = q;
      for (int j = 0; j < K::kNumParams; ++j) moved[j] += move * (j % 2 == 0 ? 1.0 : -1.0);
      const BiconicSagJacobian before(moved.data(), true);
      for (const auto& p : Points()) {
        double z, z_start, z_near;
        ASSERT_TRUE(surface.Sag(p.x(), p.y(), &z));
        ASSERT_TRUE(before.Sag(p.x(), p.y(), &z_start));
        for (const double start : {z_start, z + 0.05}) {
          ASSERT_TRUE(surface.SagNear(p.x(), p.y(), start, &z_near));
          worst = std::max(worst, std::abs(z_near - z));
          ++compared;
        }
      }
    }
  }
  EXPECT_EQ(compared, 3 * 2 * 200 * 2);
  RecordProperty("worst_mm", fmt::format("{:.3g}", worst));
  EXPECT_LT(worst, kAcceptanceMm);
  EXPECT_LT(worst, kRegressionMm);
  // Where the kernel refuses, so does the warm root, whatever its start; untilted, it is Sag itself.
  const std::array<double, K::kNumParams> steep = {0.25, 0.25, 0, 0, 0, 0, 0, 0, 0.01, 0};
  const BiconicSagJacobian sphere(steep.data(), true);
  double z;
  EXPECT_FALSE(sphere.SagNear(4.5, 0.0, 0.0, &z));
  EXPECT_TRUE(sphere.SagNear(1.0, 0.5, 3.0, &z));
  double z_sag;
  ASSERT_TRUE(sphere.Sag(1.0, 0.5, &z_sag));
  EXPECT_NEAR(z, z_sag, kRegressionMm);
  const BiconicSagJacobian untilted(Cases()[1].data(), false);
  double z_untilted;
  ASSERT_TRUE(untilted.Sag(1.0, 0.5, &z_untilted));
  ASSERT_TRUE(untilted.SagNear(1.0, 0.5, 0.3, &z));
  EXPECT_EQ(z, z_untilted);
}

TEST(BiconicJacobian, AgreesWithCentralDifferences) {
  // Independent of the kernel's jets: central differences of the sag itself, step 1e-6 (truncation ~1e-12,
  // rounding ~1e-16 / 1e-6 = 1e-10). Measured max 1.1e-10 on 2026-12-01 (relative to the point's largest
  // derivative): regression bound 1e-9; acceptance 1e-7, a hundred times the difference quotient's own error.
  constexpr double kStep = 1e-6;
  constexpr double kAcceptance = 1e-7;
  constexpr double kRegression = 1e-9;
  double worst = 0;
  for (const auto& q : Cases()) {
    const BiconicSagJacobian surface(q.data(), true);
    for (const auto& p : Points()) {
      double z, dz[K::kNumParams];
      ASSERT_TRUE(surface.Evaluate(p.x(), p.y(), &z, dz));
      const double scale = std::max(1.0, Eigen::Map<const Eigen::Matrix<double, K::kNumParams, 1>>(dz).cwiseAbs().maxCoeff());
      for (int j = 0; j < K::kNumParams; ++j) {
        auto plus = q, minus = q;
        plus[j] += kStep;
        minus[j] -= kStep;
        double zp, zm;
        ASSERT_TRUE(K::Sag(plus.data(), p.x(), p.y(), &zp, true));
        ASSERT_TRUE(K::Sag(minus.data(), p.x(), p.y(), &zm, true));
        worst = std::max(worst, std::abs(dz[j] - (zp - zm) / (2 * kStep)) / scale);
      }
    }
  }
  RecordProperty("worst", fmt::format("{:.3g}", worst));
  EXPECT_LT(worst, kAcceptance);
  EXPECT_LT(worst, kRegression);
}

TEST(BiconicJacobian, RefusesWhereTheKernelDoes) {
  // A steep sphere (r = 4 mm) is undefined beyond 4 mm: no value, no NaN.
  const std::array<double, K::kNumParams> q = {0.25, 0.25, 0, 0, 0, 0, 0, 0, 0.01, 0};
  for (const bool tilted : {false, true}) {
    const BiconicSagJacobian surface(q.data(), tilted);
    double z, dz[K::kNumParams];
    EXPECT_FALSE(surface.Evaluate(4.5, 0.0, &z, dz));
    EXPECT_TRUE(surface.Evaluate(1.0, 0.5, &z, dz));
    EXPECT_TRUE(std::isfinite(z));
  }
}

}  // namespace
}  // namespace topocal::topo
