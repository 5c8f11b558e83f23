#include "model/null_screen_layout.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "model/config.h"
#include "model/surface.h"
#include "util/io.h"

namespace topocal::model {
namespace {

// Same floating-point operations as DesignNullScreen: the traced centre must equal the designed target to rounding.
constexpr double kSameTraceToleranceMm = 1e-12;
// Unroll/RollUp round trip: a few ulps of ~100 mm coordinates through sin/cos/atan2.
constexpr double kRoundTripToleranceMm = 1e-11;
// Sheet distance along a generator equals the slant difference: exact up to rounding of ~100 mm norms.
constexpr double kGeneratorToleranceMm = 1e-11;
// Chord on the cone vs straight distance on the sheet (= geodesic on the cone): for points d <= 0.05 mm apart
// on a surface of normal curvature <= 1/rho, rho >= 2.9 mm on the used part, they differ by at most
// d^3 / (24 rho^2) = 6.2e-7 mm.
constexpr double kNearbyDistanceToleranceMm = 1e-6;
// Arc length along a circle z = const, as polyline sums of n = 200000 chords on both sides. A chord of angle a
// falls short of its arc by a^2/24 relative; the cone turns by dphi per chord, the sheet by dpsi = dphi sin(phi_c),
// so the sums differ by (dphi^2 - dpsi^2)/24 = 3.4e-11 relative (dphi = 5.8/n); rounding of the sums ~1e-12.
constexpr double kArcLengthRelTolerance = 1e-9;
// Outline points re-imaged through the reference sphere by the forward solver land on the spot circle to the
// Newton step tolerance (1e-13 mm at P2) scaled by the image magnification, as in null_screen_test.cc.
constexpr double kReimageToleranceMm = 1e-10;

Config PaperConfig() { return LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json"); }

ConeDevelopment PaperDevelopment(double cut_rad = 0.3) {
  const auto c = PaperConfig();
  return {c.topographer.cone_vertex_z_mm, c.topographer.cone_semi_angle_deg * M_PI / 180.0, cut_rad};
}

// A point of the paper's cone at slant s and azimuth phi.
Eigen::Vector3d ConePoint(const ConeDevelopment& d, double s, double phi) {
  const double rho = s * std::sin(d.semi_angle_rad);
  return {rho * std::cos(phi), rho * std::sin(phi), d.apex_z_mm + s * std::cos(d.semi_angle_rad)};
}

// Even-odd point-in-polygon test.
bool Contains(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  bool inside = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const auto& a = poly[i];
    const auto& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

bool SegmentsCross(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r,
                   const Eigen::Vector2d& s) {
  const double d1 = Cross(q - p, r - p), d2 = Cross(q - p, s - p);
  const double d3 = Cross(s - r, p - r), d4 = Cross(s - r, q - r);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}

TEST(ConeDevelopment, SectorAngleIsTwoPiSinSemiAngle) {
  const auto d = PaperDevelopment();
  EXPECT_NEAR(d.SectorAngleRad(), 2.0 * M_PI * std::sin(10.79 * M_PI / 180.0), 1e-15);
  // 67.4 deg: the paper's cone opens to a sector of about 67 degrees.
  EXPECT_NEAR(d.SectorAngleRad() * 180.0 / M_PI, 67.40, 0.01);
}

TEST(ConeDevelopment, RollUpInvertsUnroll) {
  const auto d = PaperDevelopment();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> s_dist(10.0, 100.0), phi_dist(-M_PI, M_PI);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d p = ConePoint(d, s_dist(rng), phi_dist(rng));
    const Eigen::Vector2d q = d.Unroll(p);
    const double psi = std::atan2(q.y(), q.x());
    EXPECT_GE(psi, -1e-15);
    EXPECT_LT(psi, d.SectorAngleRad() + 1e-15);
    EXPECT_NEAR((d.RollUp(q) - p).norm(), 0.0, kRoundTripToleranceMm);
    EXPECT_NEAR(q.norm(), d.SlantMm(p), kRoundTripToleranceMm);
  }
}

TEST(ConeDevelopment, PreservesDistancesAlongGenerators) {
  const auto d = PaperDevelopment();
  for (double phi : {-3.0, -1.0, 0.0, 0.31, 2.0, 3.1}) {
    const Eigen::Vector3d p = ConePoint(d, 20.0, phi), q = ConePoint(d, 87.5, phi);
    EXPECT_NEAR((d.Unroll(p) - d.Unroll(q)).norm(), (p - q).norm(), kGeneratorToleranceMm) << "phi " << phi;
  }
}

TEST(ConeDevelopment, PreservesArcLengthAlongCircles) {
  const auto d = PaperDevelopment();
  constexpr int kSegments = 200000;
  for (double s : {18.0, 50.0, 88.0}) {
    const double phi0 = d.cut_azimuth_rad + 0.1, phi1 = d.cut_azimuth_rad + 5.9;  // stays on one side of the cut
    double cone_len = 0, sheet_len = 0;
    for (int k = 0; k < kSegments; ++k) {
      const double a = phi0 + (phi1 - phi0) * k / kSegments, b = phi0 + (phi1 - phi0) * (k + 1) / kSegments;
      const Eigen::Vector3d p = ConePoint(d, s, a), q = ConePoint(d, s, b);
      cone_len += (p - q).norm();
      sheet_len += (d.Unroll(p) - d.Unroll(q)).norm();
    }
    EXPECT_NEAR(sheet_len / cone_len, 1.0, kArcLengthRelTolerance) << "s " << s;
  }
}

TEST(ConeDevelopment, NearbyPointsKeepTheirDistance) {
  const auto d = PaperDevelopment();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> s_dist(16.0, 90.0), phi_dist(-M_PI, M_PI), step(-0.035, 0.035);
  for (int i = 0; i < 2000; ++i) {
    const double s = s_dist(rng), phi = phi_dist(rng);
    const Eigen::Vector3d p = ConePoint(d, s, phi);
    const double rho = s * std::sin(d.semi_angle_rad);
    // A neighbour within ~0.05 mm: displacement ds along the generator and rho dphi along the circle.
    const Eigen::Vector3d q = ConePoint(d, s + step(rng), phi + step(rng) / rho);
    const Eigen::Vector2d uq = d.UnrollNear(q, d.PsiRad(p));  // same branch even next to the cut
    EXPECT_NEAR((d.Unroll(p) - uq).norm(), (p - q).norm(), kNearbyDistanceToleranceMm);
  }
}

TEST(ConeDevelopment, PrintedFaceUpBecomesTheInsideOfTheCone) {
  // Moving along the generator then counter-clockwise in azimuth must turn counter-clockwise on the sheet
  // (printed face towards the viewer), because e_s x e_phi is the cone's inward normal.
  const auto d = PaperDevelopment();
  const double s = 60.0, phi = 1.0, h = 1e-4;
  const Eigen::Vector3d p = ConePoint(d, s, phi);
  const Eigen::Vector3d es = ConePoint(d, s + h, phi) - p, ephi = ConePoint(d, s, phi + h) - p;
  const Eigen::Vector3d inward(-std::cos(phi), -std::sin(phi), 0.0);
  EXPECT_GT(es.cross(ephi).dot(inward), 0.0);
  const Eigen::Vector2d us = d.Unroll(ConePoint(d, s + h, phi)) - d.Unroll(p);
  const Eigen::Vector2d uphi = d.Unroll(ConePoint(d, s, phi + h)) - d.Unroll(p);
  EXPECT_GT(Cross(us, uphi), 0.0);
}

TEST(NullScreenLayout, CentresTraceToTheDesignedTargets) {
  const auto c = PaperConfig();
  const Topographer topo{c.topographer};
  const auto design = DesignNullScreen(c.ideal_image, c.topographer);
  for (const auto& t : design.targets) {
    const auto p = TraceImagePointToCone(topo, t.ideal_mm);
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR((*p - t.on_cone_mm).norm(), 0.0, kSameTraceToleranceMm);
  }
}

TEST(NullScreenLayout, PaperHasOneClosedOutlinePerSpotAroundItsTarget) {
  const auto c = PaperConfig();
  const NullScreenLayoutOptions options;
  const auto layout = LayoutNullScreen(c.ideal_image, c.topographer, options);
  EXPECT_TRUE(layout.failures.empty());
  ASSERT_EQ(layout.outlines.size(), 624u);
  const double t = std::tan(layout.development.semi_angle_rad);
  for (const auto& o : layout.outlines) {
    ASSERT_EQ(o.sheet_mm.size(), static_cast<size_t>(options.outline_points));
    // On the cone.
    for (const auto& p : o.on_cone_mm) {
      EXPECT_NEAR(p.head<2>().norm(), t * (p.z() - layout.development.apex_z_mm), 1e-9);
    }
    // Contains its target, on the sheet.
    EXPECT_TRUE(Contains(o.sheet_mm, o.target_sheet_mm)) << o.id.ring << "," << o.id.index;
    // Closes without jumps: no edge (including last -> first) longer than a quarter of the perimeter.
    double perimeter = 0, longest = 0;
    for (size_t i = 0; i < o.sheet_mm.size(); ++i) {
      const double e = (o.sheet_mm[(i + 1) % o.sheet_mm.size()] - o.sheet_mm[i]).norm();
      perimeter += e;
      longest = std::max(longest, e);
    }
    EXPECT_LT(longest, 0.25 * perimeter);
    // Simple polygon: no two non-adjacent edges cross.
    const size_t n = o.sheet_mm.size();
    for (size_t i = 0; i < n; ++i) {
      for (size_t j = i + 2; j < n; ++j) {
        if (i == 0 && j == n - 1) continue;
        ASSERT_FALSE(SegmentsCross(o.sheet_mm[i], o.sheet_mm[i + 1], o.sheet_mm[j], o.sheet_mm[(j + 1) % n]))
            << "outline " << o.id.ring << "," << o.id.index << " crosses itself";
      }
    }
    // Within the rims, with the margin to spare.
    for (const auto& q : o.sheet_mm) {
      EXPECT_GE(q.norm(), layout.inner_slant_mm + options.rim_margin_mm - 1e-9);
      EXPECT_LE(q.norm(), layout.outer_slant_mm - options.rim_margin_mm + 1e-9);
    }
  }
}

TEST(NullScreenLayout, OutlinesReimageOntoTheSpotCircles) {
  // Independent check of the backward trace: the forward solver (Eq. 15) sends every outline point through the
  // reference sphere back onto the circle of radius spot_radius_um around its ideal spot.
  const auto c = PaperConfig();
  const Topographer topo{c.topographer};
  const Surface sphere = Sphere{c.topographer.re_mm, 0.0};
  const auto layout = LayoutNullScreen(c.ideal_image, c.topographer);
  const auto ideal = IdealImage(c.ideal_image);
  const double r_mm = c.ideal_image.spot_radius_um * 1e-3;
  size_t k = 0;
  for (size_t i = 0; i < layout.outlines.size(); i += 13) {
    const auto& o = layout.outlines[i];
    while (ideal[k].id != o.id) ++k;
    const auto centre_p2 = SolveReflectionPoint(sphere, topo, o.target_on_cone_mm, Eigen::Vector2d::Zero());
    ASSERT_TRUE(centre_p2.has_value());
    for (const auto& p : o.on_cone_mm) {
      const auto p2 = SolveReflectionPoint(sphere, topo, p, centre_p2->head<2>());
      ASSERT_TRUE(p2.has_value());
      const Eigen::Vector2d img = topo.ImageOf(*p2);
      EXPECT_NEAR((img - ideal[k].position_mm).norm(), r_mm, kReimageToleranceMm);
    }
  }
}

TEST(NullScreenLayout, OutlinesAreElongatedAlongTheGenerators) {
  // The null screen's spots are elongated ellipses (paper Sec. 2): longer along the generator than across it.
  const auto c = PaperConfig();
  const auto layout = LayoutNullScreen(c.ideal_image, c.topographer);
  for (const auto& o : layout.outlines) {
    const Eigen::Vector2d radial = o.target_sheet_mm.normalized(), across(-radial.y(), radial.x());
    double rmin = 1e9, rmax = -1e9, amin = 1e9, amax = -1e9;
    for (const auto& q : o.sheet_mm) {
      rmin = std::min(rmin, q.dot(radial));
      rmax = std::max(rmax, q.dot(radial));
      amin = std::min(amin, q.dot(across));
      amax = std::max(amax, q.dot(across));
    }
    EXPECT_GT(rmax - rmin, amax - amin) << o.id.ring << "," << o.id.index;
  }
}

TEST(NullScreenLayout, SeamAvoidsOutlinesWhenChosenAutomatically) {
  const auto c = PaperConfig();
  const auto count_crossing = [](const NullScreenLayout& l) {
    int n = 0;
    for (const auto& o : l.outlines) n += o.crosses_seam ? 1 : 0;
    return n;
  };
  const auto automatic = LayoutNullScreen(c.ideal_image, c.topographer);
  // A seam forced through the azimuth of a target cuts at least that outline.
  const auto& target = automatic.outlines[100].target_on_cone_mm;
  NullScreenLayoutOptions forced;
  forced.cut_azimuth_rad = std::atan2(target.y(), target.x());
  const auto through = LayoutNullScreen(c.ideal_image, c.topographer, forced);
  EXPECT_TRUE(through.outlines[100].crosses_seam);
  EXPECT_LE(count_crossing(automatic), count_crossing(through));
  EXPECT_LT(count_crossing(automatic), count_crossing(through));
}

TEST(NullScreenLayout, CountsOverlappingSpotCircles) {
  auto c = PaperConfig();
  EXPECT_EQ(LayoutNullScreen(c.ideal_image, c.topographer).overlapping_pairs, 0);
  // Neighbours on ring i (n = 8 i spots on radius rho_i) are 2 rho_i sin(pi / n) apart: 23.73 um on ring 1, then
  // slowly less (22.9 um on ring 12); rings are 29 um apart and second neighbours ~46 um. With 11.8 um circles
  // (23.6 um apart at touching) every ring but the first has all its n neighbour pairs overlapping.
  c.ideal_image.spot_radius_um = 11.8;
  int expected = 0;
  const auto& p = c.ideal_image;
  for (int i = 1; i <= p.rings_N + 1; ++i) {
    const int n = p.eta0 + (i - 1) * p.eta;
    const double rho_um = 1e3 * (p.rho0_mm + (i - 1) * (p.rhoN_mm - p.rho0_mm) / p.rings_N);
    if (2.0 * rho_um * std::sin(M_PI / n) < 2.0 * p.spot_radius_um) expected += n;
  }
  EXPECT_EQ(expected, 624 - 8);
  EXPECT_EQ(LayoutNullScreen(c.ideal_image, c.topographer).overlapping_pairs, expected);
}

TEST(NullScreenLayout, RejectsInvalidOptions) {
  const auto c = PaperConfig();
  NullScreenLayoutOptions o;
  o.outline_points = 3;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("outline_points"), std::string::npos);
  EXPECT_THROW(LayoutNullScreen(c.ideal_image, c.topographer, o), util::InputError);
}

}  // namespace
}  // namespace topocal::model
