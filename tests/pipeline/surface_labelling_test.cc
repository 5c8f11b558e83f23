// The predict-and-label loop (pipeline/surface_labelling.h) on the spot-identity capture set: the identities the
// lattice growth leaves out along strong blend zones come back through the reconstructed surface, and none is wrong.
#include "pipeline/surface_labelling.h"

#include <gtest/gtest.h>

#include <map>
#include <utility>

#include <fmt/format.h>

#include "correct/spot_index.h"
#include "correct/spot_render.h"
#include "pipeline/capture_quality.h"
#include "tests/correct/capture_eyes.h"

namespace topocal::pipeline {
namespace {

struct Case {
  int visible = 0, lattice = 0, labelled = 0, wrong = 0;
  bool reconstructed = false;
};

// Identities as the lattice gives them (correct::IndexSpots on the detections' distorted mm), then the loop through
// the device; scored against the renderer's identity of every detection.
Case RunCase(const std::vector<correct::SpotToRender>& detections, const model::Device& device,
             const model::Config& config) {
  std::vector<Eigen::Vector2d> mm;
  std::map<std::pair<double, double>, model::SpotId> truth;
  Case c;
  for (const auto& s : detections) {
    mm.push_back(device.camera.DetectionPlaneFromPixel(s.centre_px));
    truth[{mm.back().x(), mm.back().y()}] = s.id;
    c.visible += s.id.ring != 0;
  }
  const auto idx = correct::IndexSpots(mm, config.ideal_image);
  SpotMeasurement m;
  for (const auto& s : idx.spots) m.detected.push_back({s.id, mm[s.detection]});
  m.spots = UndistortSpots(m.detected, device.distortion);
  for (int k : idx.unassigned_detections) m.free_mm.push_back(mm[k]);
  m.missing_ids = idx.missing;
  m.capture.designed = static_cast<int>(idx.spots.size() + idx.missing.size());
  m.capture.identified = m.capture.usable = static_cast<int>(idx.spots.size());
  c.lattice = m.capture.identified;
  const auto analysis = LabelThroughSurface(
      &m, device, config, [&](const auto& s) { return AnalyzeThroughDevice(s, device, config, nullptr); });
  c.reconstructed = analysis.reconstruction.ok;
  for (const auto& d : m.detected) {
    const model::SpotId& id = truth.at({d.position_mm.x(), d.position_mm.y()});
    if (id == d.id) ++c.labelled;
    else ++c.wrong;
  }
  return c;
}

// The surface recovered from a cornea's identified spots images them back where the camera saw them: the prediction
// the labelling relies on, through an assembled device (screen moved, principal point off, distortion).
TEST(SurfaceLabelling, TheRecoveredSurfacePredictsTheSpotsItWasRecoveredFrom) {
  auto config = correct::testing::PaperConfig();
  config.reconstruction.surface_model = "auto";
  for (const auto& eye : correct::testing::Eyes()) {
    const model::Device device = correct::testing::AssembledDevice(1);
    const auto truth = correct::SpotsOnSensor(eye.surface, config.ideal_image, config.topographer, device);
    std::vector<model::PlaneSpot> detected;
    std::vector<model::SpotId> ids;
    for (size_t i = 0; i < truth.spots.size(); ++i) {
      detected.push_back({truth.spots[i].id, truth.position_mm[i]});
      ids.push_back(truth.spots[i].id);
    }
    const auto analysis = AnalyzeThroughDevice(UndistortSpots(detected, device.distortion), device, config, nullptr);
    ASSERT_TRUE(analysis.reconstruction.ok) << eye.name;
    const auto predicted = PredictSpots(analysis.reconstruction, ids, device, config);
    double worst_um = 0;
    for (size_t i = 0, k = 0; i < predicted.size(); ++i) {
      while (!(detected[k].id == predicted[i].id)) ++k;
      worst_um = std::max(worst_um, 1e3 * (predicted[i].position_mm - detected[k].position_mm).norm());
    }
    EXPECT_EQ(predicted.size(), ids.size()) << eye.name;
    // The labelling's trust limit is kTrustSpacings of a spacing (~20 um here): 5 um. Measured worst 0.484 um (the
    // -8 D ablation; the biconic and the cones 0.001-0.032 um).
    EXPECT_LE(worst_um, 5.0) << eye.name;
    EXPECT_LE(worst_um, 0.6) << eye.name;
    fmt::print("{:36s}: {} of {} predicted, worst {:.3f} um; model {} adequacy {:.2f} structured {:.2f}\n", eye.name,
               predicted.size(), ids.size(), worst_um, analysis.reconstruction.surface_model,
               analysis.reconstruction.adequacy_ratio, analysis.reconstruction.structured_residual_ratio);
  }
}

TEST(SurfaceLabelling, StrongBlendZonesAreIdentifiedThroughTheSurfaceWithNoWrongIdentity) {
  auto config = correct::testing::PaperConfig();
  config.reconstruction.surface_model = "auto";  // as `reconstruct` measures eyes
  const double lids[][2] = {{0, 0}, {0.25, 0}, {0.30, 0.15}};
  uint32_t seed = 301;
  int wrong = 0, gained = 0;
  // Worst labelled share of the visible spots: [extreme ablation][with lids], with the lattice alone and with the
  // surface's labelling.
  double lattice_worst[2][2] = {{1, 1}, {1, 1}}, worst[2][2] = {{1, 1}, {1, 1}};
  for (const auto& eye : correct::testing::Eyes()) {
    for (int dev = 1; dev <= 2; ++dev) {
      const model::Device device = correct::testing::AssembledDevice(dev);
      const auto truth = correct::SpotsOnSensor(eye.surface, config.ideal_image, config.topographer, device);
      for (const auto& lid : lids) {
        SCOPED_TRACE(fmt::format("{}, device {}, lids {}/{}", eye.name, dev, lid[0], lid[1]));
        const auto detections = correct::HideUnderLids(correct::DropAndAddGlints(truth.spots, 0.03, 4, 12.0, seed++),
                                                       correct::LidsOver(truth.spots, lid[0], lid[1]));
        const Case c = RunCase(detections, device, config);
        EXPECT_EQ(c.wrong, 0);
        EXPECT_GE(c.labelled, c.lattice);  // the lattice's identities are all right here: none is lost
        wrong += c.wrong;
        gained += c.labelled - c.lattice;
        const double lattice = static_cast<double>(c.lattice) / c.visible;
        const double share = static_cast<double>(c.labelled) / c.visible;
        const bool with_lids = lid[0] + lid[1] > 0;
        lattice_worst[eye.extreme_ablation][with_lids] = std::min(lattice_worst[eye.extreme_ablation][with_lids], lattice);
        worst[eye.extreme_ablation][with_lids] = std::min(worst[eye.extreme_ablation][with_lids], share);
        fmt::print("{:36s} dev {} lid {:.2f}/{:.2f}: visible {:3d} lattice {:3d} ({:5.1f} %) with the surface {:3d} "
                   "({:5.1f} %) wrong {}\n",
                   eye.name, dev, lid[0], lid[1], c.visible, c.lattice, 100 * lattice, c.labelled, 100 * share,
                   c.wrong);
      }
    }
  }
  fmt::print("worst labelled share, lattice -> with the surface: clean {:.3f} -> {:.3f}, lids {:.3f} -> {:.3f}; "
             "extreme ablations clean {:.3f} -> {:.3f}, lids {:.3f} -> {:.3f}; {} identities gained, {} wrong\n",
             lattice_worst[0][0], worst[0][0], lattice_worst[0][1], worst[0][1], lattice_worst[1][0], worst[1][0],
             lattice_worst[1][1], worst[1][1], gained, wrong);
  // The gates: >= 95 % of the visible spots on clean images, >= 90 % with lids. Measured 1.000 and 1.000
  // (the lattice alone: 0.993 and 0.989).
  EXPECT_GE(worst[0][0], 0.95);
  EXPECT_GE(worst[0][1], 0.90);
  EXPECT_GE(worst[0][0], 0.999);
  EXPECT_GE(worst[0][1], 0.999);
  // The +6 D hyperopic and -8 D myopic ablations: the surface's identities are kept only while the surface model
  // represents them, and on the hyperopic eye it does not even with every spot right (structured residual 0.52 x
  // against 0.4 from exact spots, the first test), so the identities stop where it last did. Regression bounds near
  // today's 0.610 clean and 0.729 with lids (the lattice alone: 0.460 and 0.537).
  EXPECT_GE(worst[1][0], 0.58);
  EXPECT_GE(worst[1][1], 0.70);
  EXPECT_GE(gained, 400);  // measured 457
}

// The detection as `detect` writes it carries the surface's identities (WithSurfaceIdentities): a free detection the
// surface identified moves from the unassigned blobs to the spots, flagged surface_labelled and no longer missing; a
// spot the surface rejected moves to the excluded ones, flagged surface_outlier.
TEST(SurfaceLabelling, TheDetectionCarriesTheSurfacesIdentities) {
  const auto located_at = [](model::SpotId id, double x_mm) {
    correct::LocatedSpot s;
    s.id = id;
    s.position_mm = {x_mm, 0.5};
    return s;
  };
  correct::DetectAndIndexResult located;
  located.spots = {located_at({1, 0}, 0.0), located_at({1, 1}, 1.0)};
  located.unassigned = {located_at({0, 0}, 2.0), located_at({0, 1}, 3.0)};
  located.missing = {{1, 2}, {1, 3}};
  SpotMeasurement labelled;
  labelled.detected = {{{1, 0}, {0.0, 0.5}}, {{1, 1}, {1.0, 0.5}}, {{1, 2}, {2.0, 0.5}}};
  labelled.capture.surface_outliers = {{1, 1}};
  const auto out = WithSurfaceIdentities(located, labelled);
  ASSERT_EQ(out.spots.size(), 2u);
  EXPECT_EQ(out.spots[0].id, (model::SpotId{1, 0}));
  EXPECT_EQ(out.spots[0].flags, 0u);
  EXPECT_EQ(out.spots[1].id, (model::SpotId{1, 2}));
  EXPECT_EQ(out.spots[1].flags, static_cast<unsigned>(correct::kSurfaceLabelled));
  EXPECT_EQ(out.spots[1].position_mm.x(), 2.0);
  ASSERT_EQ(out.excluded.size(), 1u);
  EXPECT_EQ(out.excluded[0].id, (model::SpotId{1, 1}));
  EXPECT_EQ(out.excluded[0].flags, static_cast<unsigned>(correct::kSurfaceOutlier));
  ASSERT_EQ(out.unassigned.size(), 1u);
  EXPECT_EQ(out.unassigned[0].position_mm.x(), 3.0);
  EXPECT_EQ(out.missing, (std::vector<model::SpotId>{{1, 3}}));
}

}  // namespace
}  // namespace topocal::pipeline
