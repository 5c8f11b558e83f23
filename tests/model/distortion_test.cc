#include "model/distortion.h"

#include <cmath>

#include <gtest/gtest.h>

namespace topocal::model {
namespace {

// Round trip bound of the issue: inverse(forward(x)) == x to 1e-10 mm over the whole image.
constexpr double kRoundTripToleranceMm = 1e-10;
// The paper's detection-plane field: spots reach 0.45 mm with the strongest distortion; the whole image is taken
// as the disc of radius 0.5 mm inscribed in the [-0.5, 0.5] mm square of the paper's figures. (The square's corners
// lie beyond the fold of sigma = 2e-4 barrel distortion at r = 0.677 mm, where no inverse exists.)
constexpr double kFieldRadiusMm = 0.5;

void ExpectRoundTrip(const Distortion& d) {
  int n = 0;
  for (double x = -kFieldRadiusMm; x <= kFieldRadiusMm + 1e-12; x += 0.025) {
    for (double y = -kFieldRadiusMm; y <= kFieldRadiusMm + 1e-12; y += 0.025) {
      const Eigen::Vector2d p(x, y);
      if (p.norm() > kFieldRadiusMm + 1e-12) continue;
      const auto back = Undistort(d, Distort(d, p));
      ASSERT_TRUE(back.has_value()) << DescribeDistortion(d) << " at " << x << "," << y;
      EXPECT_LT((*back - p).norm(), kRoundTripToleranceMm);
      ++n;
    }
  }
  EXPECT_GT(n, 1200);  // ~pi/4 of the 41 x 41 grid
}

TEST(Seidel, RoundTripZeroMildStrong) {
  for (double sigma : {0.0, 1.41e-6, -6.3e-5, 2.0e-4, -2.0e-4}) {
    ExpectRoundTrip(SeidelParams{sigma, -0.065, 0.0, 0.0});
  }
  ExpectRoundTrip(SeidelParams{2.0e-4, -0.065, 0.03, -0.02});  // with a distortion centre
}

TEST(Brown, RoundTripZeroMildStrong) {
  LensParams b;
  ExpectRoundTrip(b);
  b.k = {-2.0, 10.0, 1e-3, -2e-3, 0.0};
  ExpectRoundTrip(b);
  b.k = {-19.7, 80.0, 5e-3, 4e-3, -200.0};
  b.centre_x_mm = 0.02;
  ExpectRoundTrip(b);
}

TEST(Seidel, MatchesEquation18) {
  const SeidelParams s{2.0e-4, -0.065, 0.0, 0.0};
  const Eigen::Vector2d p(0.3, -0.2);
  const double c = 2.0e-4 / std::pow(-0.065, 3);
  const Eigen::Vector2d expected = p * (1 + c * p.squaredNorm());
  EXPECT_LT((Distort(s, p) - expected).norm(), 1e-16);
  // sigma > 0 with M_T < 0 is barrel: points move inwards.
  EXPECT_LT(Distort(s, p).norm(), p.norm());
}

TEST(Seidel, BeyondTheBarrelFoldThereIsNoInverse) {
  const SeidelParams s{2.0e-4, -0.065, 0.0, 0.0};
  const double c = 2.0e-4 / std::pow(-0.065, 3);
  const double r_fold = std::sqrt(-1.0 / (3.0 * c));
  const double r_max = r_fold * (1 + c * r_fold * r_fold);  // largest distorted radius
  EXPECT_FALSE(Undistort(s, Eigen::Vector2d(1.01 * r_max, 0.0)).has_value());
  EXPECT_TRUE(Undistort(s, Eigen::Vector2d(0.95 * r_max, 0.0)).has_value());
}

// The fold of Eq. 18 has one owner (SeidelRadial::RadialDerivative and its closed-form root); the three ways it is
// used must agree: the closed-form radius, the Brown scan-and-bisect of the same lens (k1 = sigma f^2 / M_T^3), and
// the configuration's largest fold-free sigma at that radius.
TEST(Seidel, TheFoldIsWhereTheRadialDerivativeVanishesInEveryForm) {
  const double sigma = 2.0e-4, m = -0.065, focal_mm = 5.2;
  const SeidelParams s{sigma, m, 0.0, 0.0};
  const double c = SeidelRadial::Coefficient(s.AsArray().data());
  const double r2 = SeidelRadial::FoldRadiusSquaredMm2(c);
  EXPECT_NEAR(SeidelRadial::RadialDerivative(c, r2), 0.0, 1e-15);
  const double r_fold = FoldRadiusMm(s, 10.0, 0.0);
  EXPECT_EQ(r_fold, std::sqrt(r2));
  EXPECT_TRUE(std::isinf(FoldRadiusMm(s, 0.9 * r_fold, 0.0)));                      // beyond the searched disc
  EXPECT_TRUE(std::isinf(FoldRadiusMm(SeidelParams{-sigma, m, 0, 0}, 10.0, 0.0)));  // pincushion never folds
  // Brown's fold is found by a 1000-step scan and bisection to 1e-15 of the searched s range: agreement to 1e-12 mm
  // is far above that floor and far below anything a pixel (1.12e-3 mm) could notice.
  EXPECT_NEAR(FoldRadiusMm(SeidelToBrown(s, focal_mm), 10.0, 0.0), r_fold, 1e-12);
  EXPECT_NEAR(SeidelRadial::MaxFoldFreeSigmaPerMm2(m, r_fold), sigma, 1e-15 * sigma);
}

TEST(Conversion, SeidelAndBrownAgree) {
  const SeidelParams s{-6.3e-5, -0.065, 0.01, 0.0};
  const LensParams b = SeidelToBrown(s, 5.2);
  EXPECT_NEAR(BrownK1ToSeidelSigma(b.k[0], -0.065, 5.2), s.sigma_per_mm2, 1e-20);
  for (double x : {-0.4, 0.1, 0.35}) {
    const Eigen::Vector2d p(x, 0.5 * x);
    EXPECT_LT((Distort(s, p) - Distort(b, p)).norm(), 1e-15);
  }
}

TEST(Brown, MatchesOpenCvFormula) {
  // Hand-evaluated OpenCV model (k1,k2,p1,p2,k3) at one normalised point.
  const double k[5] = {0.1, -0.05, 0.001, -0.002, 0.01};
  const double xn[2] = {0.3, -0.2};
  double xd[2];
  BrownConrady::DistortNormalized(k, xn, xd);
  const double r2 = 0.13;
  const double radial = 1 + 0.1 * r2 - 0.05 * r2 * r2 + 0.01 * r2 * r2 * r2;
  EXPECT_NEAR(xd[0], 0.3 * radial + 2 * 0.001 * 0.3 * -0.2 + -0.002 * (r2 + 2 * 0.09), 1e-16);
  EXPECT_NEAR(xd[1], -0.2 * radial + 0.001 * (r2 + 2 * 0.04) + 2 * -0.002 * 0.3 * -0.2, 1e-16);
}

}  // namespace
}  // namespace topocal::model
