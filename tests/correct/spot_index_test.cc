// Spot indexing: 100 % correct identities on every sigma of the paper's Table IV and on corneas beyond the paper's,
// with 10 % of the spots missing and spurious glints.
#include "correct/spot_index.h"

#include <map>
#include <random>
#include <tuple>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "correct/spot_truth.h"
#include "model/freeform_test_set.h"
#include "model/null_screen.h"
#include "synthetic.h"

namespace topocal::correct {
namespace {

constexpr double kDropFraction = 0.10;  // up to 10 % missing spots
constexpr int kGlints = 6;              // "a few" spurious blobs
// Glints closer than a spot's radius plus a blur margin would merge with it into one blob (see DropAndAddGlints).
constexpr double kGlintClearancePx = 12.0;

struct Case {
  std::string name;
  model::BiconicParams cornea;
  double sigma;
};

std::vector<Case> Cases() {
  const auto cfg = testing::PaperConfig();
  std::vector<Case> cases;
  for (const double s : cfg.distortion.sigmas_per_mm2) cases.push_back({fmt::format("paper sigma {}", s), cfg.cornea, s});
  model::BiconicParams a{7.2, 7.9, 0.3, -0.6, 123.0};
  model::BiconicParams sphere{7.0, 7.0, 0.0, 0.0, 0.0};
  model::BiconicParams b{8.0, 7.4, -0.2, -0.2, 95.0};
  model::BiconicParams steep{6.5, 7.1, -0.5, 0.2, 250.0};
  for (const double s : {-2e-4, 0.0, 2e-4}) {
    cases.push_back({fmt::format("rx7.2 ry7.9 k0.3/-0.6 a123 sigma {}", s), a, s});
    cases.push_back({fmt::format("sphere r7.0 sigma {}", s), sphere, s});
    cases.push_back({fmt::format("rx8.0 ry7.4 a95 sigma {}", s), b, s});
    cases.push_back({fmt::format("rx6.5 ry7.1 a250 sigma {}", s), steep, s});
  }
  return cases;
}

// Every real spot has its own identity, no glint (ring 0 in the truth) has one, no real spot is left unassigned.
void ExpectEveryIdentityRight(const SpotIndexing& idx, const std::vector<SpotToRender>& truth) {
  int wrong = 0, glints_assigned = 0;
  for (const auto& s : idx.spots) {
    const auto& t = truth[s.detection].id;
    if (t.ring == 0) ++glints_assigned;
    else if (!(t == s.id)) ++wrong;
  }
  int real_unassigned = 0;
  for (const int i : idx.unassigned_detections) real_unassigned += truth[i].id.ring != 0;
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(glints_assigned, 0);
  EXPECT_EQ(real_unassigned, 0) << idx.message;
}

TEST(SpotIndex, AllCorrectWithDropsAndGlints) {
  const auto cfg = testing::PaperConfig();
  const auto camera = testing::DefaultCamera();
  uint32_t seed = 1;
  for (const auto& c : Cases()) {
    SCOPED_TRACE(c.name);
    const auto truth = testing::Truth(cfg, c.cornea, c.sigma, camera);
    ASSERT_GT(truth.spots.size(), 500u);
    const auto perturbed = DropAndAddGlints(truth.spots, kDropFraction, kGlints, kGlintClearancePx, seed++);
    std::vector<Eigen::Vector2d> mm;
    for (const auto& s : perturbed) mm.push_back(camera.DetectionPlaneFromPixel(s.centre_px));
    const auto idx = IndexSpots(mm, cfg.ideal_image);
    ASSERT_TRUE(idx.ok) << idx.message;
    ExpectEveryIdentityRight(idx, perturbed);
    EXPECT_EQ(idx.spots.size() + idx.missing.size(), static_cast<size_t>(cfg.ideal_image.SpotCount()));
  }
}

// Misassembled devices: the screen tilted up to 2 deg (twice the assembly tolerance) at any azimuth,
// rolled, decentred and shifted along the axis, the principal point off — the rings are then not concentric (the
// inner rings' centre moves by ~0.8 ring spacings at 1.5 deg) — with drops and glints: every identity right.
// Before the inner-rings centre search, 1.5 deg lost all but ring 1-6's neighbourhood (185 of 624 indexed).
TEST(SpotIndex, AllCorrectOnMisalignedDevices) {
  const auto cfg = testing::PaperConfig();
  uint32_t seed = 11;
  for (const double tilt_deg : {1.0, 1.5, 2.0}) {
    for (const double azimuth_deg : {0.0, 135.0, 250.0}) {
      SCOPED_TRACE(fmt::format("tilt {} deg at {} deg", tilt_deg, azimuth_deg));
      model::Device device = model::NominalDevice(testing::DefaultCamera());
      const double az = azimuth_deg * M_PI / 180.0;
      device.screen = {tilt_deg * std::cos(az), tilt_deg * std::sin(az), 1.0, 0.2, -0.2, 0.5, 1.0};
      device.camera.principal_point_px += Eigen::Vector2d(25, -20);
      model::SeidelParams seidel;
      seidel.sigma_per_mm2 = 6.3e-5;
      device.distortion = seidel;
      const auto truth = SpotsOnSensor(model::Biconic{cfg.cornea}, cfg.ideal_image, cfg.topographer, device);
      ASSERT_EQ(truth.spots.size(), 624u);
      const auto perturbed = DropAndAddGlints(truth.spots, kDropFraction, kGlints, kGlintClearancePx, seed++);
      std::vector<Eigen::Vector2d> mm;
      // Measured as an uncalibrated unit would: through the nominal camera.
      for (const auto& s : perturbed) mm.push_back(testing::DefaultCamera().DetectionPlaneFromPixel(s.centre_px));
      const auto idx = IndexSpots(mm, cfg.ideal_image);
      ASSERT_TRUE(idx.ok) << idx.message;
      ExpectEveryIdentityRight(idx, perturbed);
    }
  }
}

TEST(SpotIndex, TooFewDetectionsIsReportedNotThrown) {
  const auto cfg = testing::PaperConfig();
  const auto idx = IndexSpots({Eigen::Vector2d(0.1, 0.1)}, cfg.ideal_image);
  EXPECT_FALSE(idx.ok);
  EXPECT_EQ(idx.unassigned_detections.size(), 1u);
  EXPECT_EQ(idx.missing.size(), static_cast<size_t>(cfg.ideal_image.SpotCount()));
}

// A dozen blobs spread over the pattern (a sensor so coarse that the spots merge into a few large blobs) once made
// the start's distance field ask OpenCV for 93 GB: refused with the reason, in bounded memory.
TEST(SpotIndex, AFewMergedBlobsAreRefusedWithTheReason) {
  const auto cfg = testing::PaperConfig();
  std::vector<Eigen::Vector2d> blobs;
  for (int k = 0; k < 12; ++k) blobs.push_back(0.02 * Eigen::Vector2d(std::cos(k * 0.52), std::sin(k * 0.52)) * (1 + k % 3));
  const auto idx = IndexSpots(blobs, cfg.ideal_image);
  EXPECT_FALSE(idx.ok);
  EXPECT_NE(idx.message.find("12 detections, fewer than the 48 spots"), std::string::npos) << idx.message;
}

// The spots of the +6 D hyperopic ablation through dense eta-6 and eta-8 screens: the blend zone bends the lattice
// so that growth from the right start keeps being refused by its own checks, and the lattice that survives slipped.
// Such a lattice is refused whole (measured 2026-12-07: 267 refused against 522 kept on 20 rings x 6 from exact spots,
// every one of the 522 wrong; 1208 against 1359 on 22 rings x 8 with 0.5 um of noise, 795 wrong), while the same
// ablation's spots with 0.5 um of noise on 20 rings x 6 are all identified and right.
TEST(SpotIndex, ALatticeItsChecksKeepRefusingIsNotTrusted) {
  const auto cfg = testing::PaperConfig();
  const auto ablation = model::FreeformTestSubset({"lasik-hyperopic-6D"}).front().surface;
  const auto spots_of = [&](int rings, int eta, double noise_um, model::IdealImageParams* ideal) {
    *ideal = cfg.ideal_image;
    ideal->rings_N = rings - 1;
    ideal->eta0 = ideal->eta = eta;
    const auto design = model::DesignNullScreen(*ideal, cfg.topographer);
    const auto image = model::SynthesizeImage(ablation, model::Topographer{cfg.topographer}, design.targets);
    std::mt19937 rng(3);
    std::normal_distribution<double> noise(0.0, noise_um * 1e-3);
    std::vector<Eigen::Vector2d> mm;
    for (const auto& s : image.spots) mm.push_back(s.position_mm + Eigen::Vector2d(noise(rng), noise(rng)));
    return std::make_pair(mm, image.spots);
  };
  model::IdealImageParams ideal;
  for (const auto& [rings, eta, noise_um] : std::vector<std::tuple<int, int, double>>{{20, 6, 0.0}, {22, 8, 0.5}}) {
    SCOPED_TRACE(fmt::format("{} rings x {}, {} um", rings, eta, noise_um));
    const auto [mm, truth] = spots_of(rings, eta, noise_um, &ideal);
    const auto idx = IndexSpots(mm, ideal);
    EXPECT_FALSE(idx.ok);
    EXPECT_TRUE(idx.spots.empty());
    EXPECT_NE(idx.message.find("the identities do not hold together"), std::string::npos) << idx.message;
  }
  const auto [mm, truth] = spots_of(20, 6, 0.5, &ideal);
  const auto idx = IndexSpots(mm, ideal);
  ASSERT_TRUE(idx.ok) << idx.message;
  int wrong = 0;
  for (const auto& s : idx.spots) wrong += !(s.id == truth[s.detection].id);
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(idx.spots.size(), truth.size());  // measured: all 1260
}

}  // namespace
}  // namespace topocal::correct
