#include "model/null_screen.h"

#include <gtest/gtest.h>

#include "model/config.h"

namespace topocal::model {
namespace {

// Law-of-reflection residual floor: unit vectors built from ~100 mm coordinates in double precision carry
// ~1e-15 relative error; 1e-12 is the bound and leaves three orders of margin.
constexpr double kReflectionTolerance = 1e-12;
// The sphere's synthetic image reproduces the ideal image to the Newton step tolerance (1e-13 mm at P2) scaled by
// the ~a/b image magnification; the bound is 1e-10 mm.
constexpr double kIdealImageToleranceMm = 1e-10;

Config PaperConfig() { return LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json"); }

TEST(IdealImage, SpotCountAndRings) {
  const auto c = PaperConfig();
  const auto spots = IdealImage(c.ideal_image);
  ASSERT_EQ(spots.size(), 624u);  // paper README item 1: 12 rings, 8 + 8(i-1) spots
  EXPECT_EQ(c.ideal_image.SpotCount(), 624);
  EXPECT_EQ(spots.front().id, (SpotId{1, 0}));
  EXPECT_EQ(spots.back().id, (SpotId{12, 95}));
  EXPECT_NEAR(spots.back().position_mm.norm(), 0.35, 1e-15);
  // Eq. 1 with sin for y: the spot at theta = 90 deg lies on +y.
  const auto& s = spots[2];  // ring 1, j = 2 of 8 -> 90 deg
  EXPECT_NEAR(s.position_mm.x(), 0.0, 1e-15);
  EXPECT_NEAR(s.position_mm.y(), 0.031, 1e-15);
}

TEST(Design, EveryRayReachesTheConeAndObeysReflection) {
  const auto c = PaperConfig();
  const auto design = DesignNullScreen(c.ideal_image, c.topographer);
  EXPECT_TRUE(design.failures.empty());
  ASSERT_EQ(design.targets.size(), 624u);
  const Topographer topo{c.topographer};
  const double t = std::tan(c.topographer.cone_semi_angle_deg * M_PI / 180.0);
  for (const auto& tp : design.targets) {
    // P3 lies on the cone.
    const double rho = tp.on_cone_mm.head<2>().norm();
    EXPECT_NEAR(rho, t * (tp.on_cone_mm.z() - c.topographer.cone_vertex_z_mm), 1e-9);
    // Law of reflection at P2 on the sphere.
    const Eigen::Vector3d inc = (tp.on_sphere_mm - topo.Pinhole()).normalized();
    const Eigen::Vector3d ref = (tp.on_cone_mm - tp.on_sphere_mm).normalized();
    const Eigen::Vector3d n = (tp.on_sphere_mm - Eigen::Vector3d(0, 0, c.topographer.re_mm)).normalized();
    const Eigen::Vector3d expected = inc - 2.0 * inc.dot(n) * n;
    EXPECT_LT((ref - expected).norm(), kReflectionTolerance);
  }
  // Paper README item 4: the outer ring lands at rho ~ 16.24 mm near z = 0.
  EXPECT_NEAR(design.targets.back().on_cone_mm.head<2>().norm(), 16.24, 0.05);
}

TEST(Synthesis, ReferenceSphereReproducesTheIdealImage) {
  const auto c = PaperConfig();
  const auto design = DesignNullScreen(c.ideal_image, c.topographer);
  const auto image = SynthesizeImage(Sphere{c.topographer.re_mm, 0.0}, Topographer{c.topographer}, design.targets);
  ASSERT_TRUE(image.failures.empty());
  ASSERT_EQ(image.spots.size(), design.targets.size());
  double worst = 0;
  for (size_t i = 0; i < image.spots.size(); ++i) {
    worst = std::max(worst, (image.spots[i].position_mm - design.targets[i].ideal_mm).norm());
  }
  EXPECT_LT(worst, kIdealImageToleranceMm);
}

void ExpectReflectionHolds(const Surface& surface, const Config& c) {
  const auto design = DesignNullScreen(c.ideal_image, c.topographer);
  const Topographer topo{c.topographer};
  const auto image = SynthesizeImage(surface, topo, design.targets);
  ASSERT_TRUE(image.failures.empty());
  for (size_t i = 0; i < image.spots.size(); ++i) {
    const auto& s = image.spots[i];
    SurfaceDerivatives d;
    ASSERT_TRUE(EvaluateSurface(surface, s.on_surface_mm.x(), s.on_surface_mm.y(), &d));
    EXPECT_NEAR(d.z, s.on_surface_mm.z(), 1e-12);
    const Eigen::Vector3d n = SurfaceNormal(d.zx, d.zy);
    const Eigen::Vector3d inc = (s.on_surface_mm - topo.Pinhole()).normalized();
    const Eigen::Vector3d ref = (design.targets[i].on_cone_mm - s.on_surface_mm).normalized();
    EXPECT_LT((ref - (inc - 2.0 * inc.dot(n) * n)).norm(), kReflectionTolerance) << "spot " << i;
    // The image point lies on the incident ray (Eq. 16).
    EXPECT_LT((topo.IncidentDirection(s.position_mm) - inc).norm(), 1e-13);
  }
}

TEST(Synthesis, LawOfReflectionHoldsOnThePaperBiconic) {
  const auto c = PaperConfig();
  ExpectReflectionHolds(Biconic{c.cornea}, c);
}

TEST(Synthesis, LawOfReflectionHoldsOnOtherBiconics) {
  const auto c = PaperConfig();
  ExpectReflectionHolds(Biconic{BiconicParams{7.2, 7.9, 0.3, -0.6, 123.0, 0.0, 0.0, 0.0}}, c);
  ExpectReflectionHolds(Biconic{BiconicParams{8.0, 8.0, -0.2, -0.2, 0.0, 0.1, -0.05, 0.02}}, c);
}

TEST(Synthesis, SpotsTheSurfaceCannotImageAreReportedByIdentity) {
  const auto c = PaperConfig();
  const auto design = DesignNullScreen(c.ideal_image, c.topographer);
  // A strongly oblate biconic defined only within ~3.3 mm: the outer rings land where it does not exist.
  const Biconic small{BiconicParams{7.8, 7.8, 4.5, 4.5, 0.0, 0.0, 0.0, 0.0}};
  const auto image = SynthesizeImage(small, Topographer{c.topographer}, design.targets);
  EXPECT_FALSE(image.failures.empty());
  EXPECT_EQ(image.spots.size() + image.failures.size(), design.targets.size());
  for (const auto& f : image.failures) EXPECT_GE(f.id.ring, 2);
  for (const auto& s : image.spots) EXPECT_TRUE(std::isfinite(s.position_mm.x()) && std::isfinite(s.position_mm.y()));
}

}  // namespace
}  // namespace topocal::model
