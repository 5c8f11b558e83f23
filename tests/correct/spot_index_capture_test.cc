// Spot identities on captures as they really are: a lid hiding a sector (upper or lower, 0-40 % of the pattern),
// keratoconus cones and refractive ablations far from any biconic, decentred and tilted eyes, assembled devices,
// drops and glints. The gate is zero wrong identities on every case (a wrong identity prints clinical numbers that
// are not); the labelled share of the visible spots is held to >= 95 % on clean patterns and >= 90 % with lids.
#include <algorithm>
#include <map>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "correct/spot_index.h"
#include "correct/spot_truth.h"
#include "tests/correct/capture_eyes.h"

namespace topocal::correct {
namespace {

using testing::AssembledDevice;
using testing::Eyes;

struct Tally {
  int visible = 0, labelled = 0, wrong = 0, glints = 0;
};

Tally Score(const SpotIndexing& idx, const std::vector<SpotToRender>& truth) {
  Tally t;
  for (const auto& s : truth) t.visible += s.id.ring != 0;
  for (const auto& s : idx.spots) {
    const auto& id = truth[s.detection].id;
    if (id.ring == 0) ++t.glints;
    else if (!(id == s.id)) ++t.wrong;
    else ++t.labelled;
  }
  return t;
}

struct LidCase {
  double upper, lower;
};

// Glints are placed on the whole pattern (clear of every designed spot, hidden or not) before the lids hide their
// sector: a glint exactly where a hidden spot would be is a spot by every positional test, and telling it apart
// needs the blob's shape (docs/spot-identification.md, "Limits").
TEST(SpotIndexCapture, LidsConesAblationsAndAssembledDevicesGiveNoWrongIdentity) {
  const auto cfg = testing::PaperConfig();
  const LidCase lids[] = {{0, 0}, {0.15, 0}, {0.25, 0}, {0.40, 0}, {0, 0.25}, {0.30, 0.15}};
  uint32_t seed = 101;
  int total_wrong = 0;
  // Worst labelled share of the visible spots: [extreme ablation][with lids].
  double worst[2][2] = {{1, 1}, {1, 1}};
  for (const auto& eye : Eyes()) {
    for (int dev = 0; dev < 2; ++dev) {
      const model::Device device = AssembledDevice(dev + static_cast<int>(seed % 3));
      const auto truth = SpotsOnSensor(eye.surface, cfg.ideal_image, cfg.topographer, device);
      ASSERT_GT(truth.spots.size(), 550u) << eye.name;
      for (const auto& lid : lids) {
        SCOPED_TRACE(fmt::format("{}, device {}, lids {}/{}", eye.name, dev, lid.upper, lid.lower));
        const auto perturbed = HideUnderLids(DropAndAddGlints(truth.spots, 0.03, 4, 12.0, seed++), LidsOver(truth.spots, lid.upper, lid.lower));
        std::vector<Eigen::Vector2d> mm;
        for (const auto& s : perturbed) mm.push_back(testing::DefaultCamera().DetectionPlaneFromPixel(s.centre_px));
        const auto idx = IndexSpots(mm, cfg.ideal_image);
        ASSERT_TRUE(idx.ok) << idx.message;
        const Tally t = Score(idx, perturbed);
        const double share = static_cast<double>(t.labelled) / t.visible;
        EXPECT_EQ(t.wrong, 0) << idx.message;
        EXPECT_EQ(t.glints, 0) << idx.message;
        total_wrong += t.wrong + t.glints;
        double& w = worst[eye.extreme_ablation][lid.upper + lid.lower > 0];
        w = std::min(w, share);
        fmt::print("{:36s} dev {} lid {:.2f}/{:.2f}: visible {:3d} labelled {:3d} ({:5.1f} %) wrong {} glints {} "
                   "refused {}\n",
                   eye.name, dev, lid.upper, lid.lower, t.visible, t.labelled, 100 * share, t.wrong, t.glints,
                   idx.dropped);
      }
    }
  }
  fmt::print("worst labelled share: clean {:.3f}, lids {:.3f}; extreme ablations: clean {:.3f}, lids {:.3f}; wrong "
             "identities {}\n",
             worst[0][0], worst[0][1], worst[1][0], worst[1][1], total_wrong);
  // The gates: >= 95 % of the visible spots on clean images, >= 90 % with lids.
  EXPECT_GE(worst[0][0], 0.95);
  EXPECT_GE(worst[0][1], 0.90);
  // The +6 D hyperopic and -8 D myopic ablations do not reach them (the blend zone compresses two or three rings to
  // half their spacing and the growth refuses what it cannot tell apart): regression bounds near today's 0.458 clean
  // and 0.516 with lids (docs/spot-identification.md). Measured: every other eye 0.995 clean, 0.992 with lids.
  EXPECT_GE(worst[1][0], 0.42);
  EXPECT_GE(worst[1][1], 0.42);
}

// A severe cone beside the apex of a dense screen (the 26-ring x 6 design of docs/screen-design.md, exact spots):
// it stretches the inner rings by ~11 % along one axis, the isotropic start search seats rings 1-3 on the cone's
// flank, and every lattice grown from there is wrong and refused. The stretched starts find the centre; the eyes the
// isotropic start already reads take the same path as before (no stretched search).
TEST(SpotIndexCapture, ASevereConeBesideTheApexOfADenseScreenIsReadFromAStretchedStart) {
  auto cfg = testing::PaperConfig();
  cfg.ideal_image = testing::DesignedScreen(cfg.ideal_image);
  const auto eyes = Eyes();
  const auto severe = std::find_if(eyes.begin(), eyes.end(), [](const auto& e) { return e.name.rfind("kc-60", 0) == 0; });
  ASSERT_NE(severe, eyes.end());
  int read = 0;
  for (int dev = 0; dev < 3; ++dev) {
    SCOPED_TRACE(fmt::format("device {}", dev));
    const auto truth = SpotsOnSensor(severe->surface, cfg.ideal_image, cfg.topographer, AssembledDevice(dev));
    std::vector<Eigen::Vector2d> mm;
    for (const auto& s : truth.spots) mm.push_back(testing::DefaultCamera().DetectionPlaneFromPixel(s.centre_px));
    const auto idx = IndexSpots(mm, cfg.ideal_image);
    const Tally t = Score(idx, truth.spots);
    fmt::print("device {}: {} of {} identified, {} wrong; {}\n", dev, t.labelled, t.visible, t.wrong, idx.message);
    EXPECT_EQ(t.wrong, 0);  // acceptance, read or refused
    if (!idx.ok) continue;
    ++read;
    // Measured 2026-12-07: 2,095 of 2,106 on devices 0 and 1 (none read before the stretched starts).
    EXPECT_GE(static_cast<double>(t.labelled) / t.visible, 0.99);
  }
  // Devices 0 and 1 read; device 2 still refused ("the identities do not hold together"), measured 2026-12-07.
  EXPECT_GE(read, 2);
}

// The dense designed screen (26 rings x 6) under lids, through assembled devices, with drops and glints: every eye of
// the set, four lid cases. Its rings are 0.4 times the paper screen's apart, so a start or a growth a ring off is
// easier to make and as consistent with itself.
TEST(SpotIndexCapture, TheDenseDesignedScreenUnderLidsGivesNoWrongIdentity) {
  auto cfg = testing::PaperConfig();
  cfg.ideal_image = testing::DesignedScreen(cfg.ideal_image);
  const LidCase lids[] = {{0.15, 0}, {0.25, 0}, {0.40, 0}, {0.30, 0.15}};
  uint32_t seed = 501;
  int wrong = 0, refused = 0, cases = 0;
  double worst_share = 1;  // of the visible spots, on the eyes other than the +6 D hyperopic ablation
  for (const auto& eye : Eyes()) {
    for (int dev = 0; dev < 2; ++dev) {
      const auto truth = SpotsOnSensor(eye.surface, cfg.ideal_image, cfg.topographer, AssembledDevice(dev));
      for (const auto& lid : lids) {
        SCOPED_TRACE(fmt::format("{}, device {}, lids {}/{}", eye.name, dev, lid.upper, lid.lower));
        // Glints a spacing of this screen (0.4 of the paper's) clear of every designed spot.
        const auto perturbed = HideUnderLids(DropAndAddGlints(truth.spots, 0.03, 4, 12.0 * 0.4, seed++),
                                             LidsOver(truth.spots, lid.upper, lid.lower));
        std::vector<Eigen::Vector2d> mm;
        for (const auto& s : perturbed) mm.push_back(testing::DefaultCamera().DetectionPlaneFromPixel(s.centre_px));
        const auto idx = IndexSpots(mm, cfg.ideal_image);
        const Tally t = Score(idx, perturbed);
        EXPECT_EQ(t.wrong + t.glints, 0) << idx.message;  // acceptance: identities right or refused
        wrong += t.wrong + t.glints;
        refused += !idx.ok;
        ++cases;
        if (eye.name != "lasik-hyperopic-6D") {
          EXPECT_TRUE(idx.ok) << idx.message;
          worst_share = std::min(worst_share, static_cast<double>(t.labelled) / t.visible);
        }
      }
    }
  }
  fmt::print("dense screen under lids: {} cases, {} refused, {} wrong; worst labelled share {:.3f}\n", cases, refused,
             wrong, worst_share);
  // Measured 2026-12-07: 3 of 72 refused (the +6 D hyperopic ablation, whose blend compresses rings), none wrong;
  // worst share 0.981 on the others. Before a lattice had to hold a quarter of rings 1-3 and before the stretched
  // starts: 12 refused and one case of 1,083 identities, all wrong (the 33 um cone, device 1, lids 30 % / 15 %).
  EXPECT_LE(refused, 3);
  EXPECT_GE(worst_share, 0.90);  // the lidded captures' gate
  EXPECT_GE(worst_share, 0.97);
}

}  // namespace
}  // namespace topocal::correct
