#include "model/ellipse_fit.h"

#include <gtest/gtest.h>

namespace topocal::model {
namespace {

// Exact points on an ellipse are fitted exactly: only rounding remains.
constexpr double kExactFitTolerance = 1e-10;

std::vector<Eigen::Vector2d> EllipsePoints(Eigen::Vector2d c, double a, double b, double beta_deg, int n, double phase) {
  std::vector<Eigen::Vector2d> pts;
  const double be = beta_deg * M_PI / 180;
  for (int i = 0; i < n; ++i) {
    const double t = phase + 2 * M_PI * i / n;
    const Eigen::Vector2d local(a * std::cos(t), b * std::sin(t));
    pts.push_back(c + Eigen::Vector2d(std::cos(be) * local.x() - std::sin(be) * local.y(),
                                      std::sin(be) * local.x() + std::cos(be) * local.y()));
  }
  return pts;
}

TEST(EllipseFit, RecoversKnownEllipses) {
  struct Case { Eigen::Vector2d c; double a, b, beta; int n; };
  for (const Case& k : {Case{{0, 0}, 0.3876, 0.3507, 17.0, 96}, Case{{0.1, -0.2}, 2.0, 0.5, -63.0, 7},
                        Case{{5, 5}, 1.0, 0.999, 89.0, 40}, Case{{0, 0}, 0.43, 0.38, -17.0, 12}}) {
    const auto e = FitEllipseDirect(EllipsePoints(k.c, k.a, k.b, k.beta, k.n, 0.3));
    ASSERT_TRUE(e.has_value());
    EXPECT_NEAR(e->a_mm, k.a, kExactFitTolerance);
    EXPECT_NEAR(e->b_mm, k.b, kExactFitTolerance);
    EXPECT_NEAR(e->beta_deg, k.beta, 1e-7);
    EXPECT_LT((e->centre_mm - k.c).norm(), kExactFitTolerance);
    EXPECT_NEAR(e->AreaMm2(), M_PI * k.a * k.b, kExactFitTolerance);
  }
}

TEST(EllipseFit, RejectsTooFewOrDegeneratePoints) {
  EXPECT_FALSE(FitEllipseDirect({{0, 0}, {1, 0}, {0, 1}, {1, 1}}).has_value());
  std::vector<Eigen::Vector2d> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(i, 2 * i);
  EXPECT_FALSE(FitEllipseDirect(line).has_value());
}

}  // namespace
}  // namespace topocal::model
