// Clinical captures end to end (capture issue, item 5): raw 4000 x 3000 images rendered through assembled devices
// with what a real capture adds — lids with their skin, lash shadows, an iris behind the pattern, defocus growing
// towards the rim, glints, tear-film break-up, motion blur — of decentred, tilted paper, keratoconic and post-LASIK
// eyes; measured as `reconstruct --image --device` measures them (pipeline::MeasureSpots, AnalyzeThroughDevice,
// JudgeMeasurement) and compared with the truth. Gates: zero wrong identities; >= 90 % of the visible spots
// identified; every measurement either refused with its reason or within twice the clean-image map limits (axial
// rms 0.20 D and |dKmax| 0.50 D over the supported disc).
// A post-LASIK eye under every artefact at once (lid, lashes, iris, defocus to 3 px, motion blur, glints, tear
// film) is measured as reconstruct measures it through a device, its U included: a map too uncertain is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "device_fixtures.h"
#include "model/freeform_test_set.h"
#include "pipeline/capture_quality.h"
#include "pipeline/measure_spots.h"
#include "pipeline/measurement_uncertainty.h"
#include "pipeline/surface_labelling.h"
#include "topo/truth_comparison.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// The clinical-capture limits: twice the clean-image ones.
constexpr double kAxialRmsD = 0.20, kKmaxD = 0.50, kLabelledShare = 0.90;

struct Capture {
  std::string name;
  model::Surface eye;
  double upper_lid = 0, lower_lid = 0, skin_dn = 0;
  correct::Artefacts artefacts;
  double defocus_rim_px = 0;  // PSF sigma at the rim (1.5 px at the centre); 0: 1 px everywhere
  int glints = 0, tear_film = 0;
};

model::Surface PaperEye() {
  auto b = testing::PaperConfig().cornea;
  b.x0_mm = 0.3;
  b.y0_mm = -0.25;
  b.tilt_x_deg = 1.5;
  b.tilt_y_deg = -2.0;
  model::Biconic s{b};
  model::FocusOnAxis(&s);
  return s;
}

model::Surface Freeform(const std::string& name) { return model::FreeformTestSubset({name}).front().surface; }

std::vector<Capture> Captures() {
  std::vector<Capture> c;
  correct::Artefacts lashes_iris;
  lashes_iris.lashes = 4;
  lashes_iris.iris_dn = 2500;
  correct::Artefacts blur = lashes_iris;
  blur.motion_blur_px = 1.5;
  blur.motion_blur_deg = 30;
  c.push_back({"paper, upper lid 20 % with skin", PaperEye(), 0.20, 0.0, 8000, {}});
  c.push_back({"paper, lids, 4 lashes, iris", PaperEye(), 0.18, 0.05, 8000, lashes_iris});
  c.push_back({"paper, defocus 1.5 -> 3.5 px, 3 glints, tear film", PaperEye(), 0.0, 0.0, 0, {}, 3.5, 3, 2});
  c.push_back({"paper, everything, motion blur 1.5 px", PaperEye(), 0.2, 0.05, 8000, blur, 3.0, 2, 2});
  c.push_back({"kc-33um-0.85mm, lids, lashes, iris", Freeform("kc-33um-0.85mm"), 0.15, 0.05, 8000, lashes_iris});
  c.push_back({"lasik-myopic-6D, upper lid 20 %, defocus 1.5 -> 3 px", Freeform("lasik-myopic-6D"), 0.2, 0.0, 8000, {},
               3.0});
  c.push_back({"lasik-myopic-6D, upper lid 20 %", Freeform("lasik-myopic-6D"), 0.2, 0.0, 8000, {}});
  return c;
}

struct Outcome {
  int visible = 0, identified = 0, wrong = 0, surface_outliers = 0, duplicates = 0;
  double adequacy = 0, structured = 0;
  bool refused = false;
  std::string reason;
  topo::TruthComparison comparison;
};

// The post-LASIK eye under every artefact at once.
Capture PostLasikEverything() {
  correct::Artefacts all;
  all.lashes = 4;
  all.iris_dn = 2500;
  all.motion_blur_px = 1.5;
  all.motion_blur_deg = 30;
  return {"lasik-myopic-6D, everything", Freeform("lasik-myopic-6D"), 0.2, 0.05, 8000, all, 3.0, 2, 2};
}

// with_uncertainty: also the U of the measurement (the spots' measured noise; the drawn device is exact here, so it
// has no covariance) and the refusal of a map too uncertain for a clinical reading (UncertaintyRefusal).
Outcome Measure(const Capture& cap, uint32_t seed, bool with_uncertainty = false) {
  const auto cfg = testing::PaperConfig();
  std::mt19937 rng(seed);
  const model::Device device = testing::DrawDevice(rng);
  const auto truth = correct::SpotsOnSensor(cap.eye, cfg.ideal_image, cfg.topographer, device);
  correct::SpotRenderOptions o;
  o.psf_sigma_px = cap.defocus_rim_px > 0 ? 1.5 : 1.0;
  o.background_dn = 1000;
  o.peak_dn = 40000;
  o.read_noise_dn = 60;
  o.gain_e_per_dn = 4;
  o.seed = seed;
  o.lids = correct::LidsOver(truth.spots, cap.upper_lid, cap.lower_lid);
  o.skin_dn = cap.skin_dn;
  o.skin_texture_dn = 0.25 * cap.skin_dn;
  o.artefacts = cap.artefacts;
  auto spots = correct::DropAndAddGlints(truth.spots, 0.0, cap.glints, 30.0, seed + 1);
  if (cap.defocus_rim_px > 0) spots = correct::GrowDefocus(spots, o.lids, o.psf_sigma_px, cap.defocus_rim_px);
  if (cap.tear_film > 0) spots = correct::BreakTearFilm(spots, o.lids, cap.tear_film, o.psf_sigma_px, seed + 2);
  spots = correct::HideUnderLids(spots, o.lids);
  const cv::Mat image = correct::RenderSpotImage(spots, device.camera.width_px, device.camera.height_px, o);

  Outcome out;
  std::map<model::SpotId, Eigen::Vector2d> where_mm;  // the visible spots' true (distorted) positions
  for (const auto& s : spots) {
    if (s.id.ring != 0) where_mm[s.id] = device.camera.DetectionPlaneFromPixel(s.centre_px);
  }
  out.visible = static_cast<int>(where_mm.size());
  SpotMeasurement m;
  try {
    m = MeasureSpots(image, device, cfg.ideal_image);
  } catch (const util::MeasurementRefused& e) {
    out.refused = true;
    out.reason = e.what();
    return out;
  }
  auto config = cfg;
  config.reconstruction.surface_model = "auto";  // as `reconstruct` without --surface-model
  const topo::Analysis analysis = LabelThroughSurface(
      &m, device, config, [&](const auto& s) { return AnalyzeThroughDevice(s, device, config, nullptr); });
  out.identified = m.capture.identified;
  // A wrong identity: the visible spot nearest to the detection is another (a right identity whose centre a lash
  // pulled by a few px is still nearest to its own spot, ~20 px from the next).
  for (const auto& d : m.detected) {
    model::SpotId nearest;
    double best = std::numeric_limits<double>::infinity();
    for (const auto& [id, mm] : where_mm) {
      if ((mm - d.distorted_mm).norm() < best) {
        best = (mm - d.distorted_mm).norm();
        nearest = id;
      }
    }
    out.wrong += !(nearest == d.id);
  }
  std::set<model::SpotId> ids;
  for (const auto& d : m.detected) ids.insert(d.id);
  out.duplicates = static_cast<int>(m.detected.size() - ids.size());
  out.surface_outliers = m.capture.surface_outliers;
  MeasurementVerdict verdict = JudgeMeasurement(m.capture, analysis);
  if (verdict.valid && with_uncertainty) {
    const auto u = PropagateMeasurementUncertainty(m.detected, device, std::nullopt, config, analysis);
    if (const auto reason = UncertaintyRefusal(u)) verdict = {false, {*reason}};
  }
  if (!verdict.valid) {
    out.refused = true;
    out.reason = verdict.reasons.front();
    return out;
  }
  out.comparison = topo::CompareWithTruth(analysis, cap.eye, config.reconstruction);
  out.adequacy = analysis.reconstruction.adequacy_ratio;
  out.structured = analysis.reconstruction.structured_residual_ratio;
  return out;
}

TEST(ClinicalCapture, EveryIdentityRightAndEveryMeasurementWithinTwiceTheCleanLimitsOrRefused) {
  int refused = 0;
  double worst_axial = 0, worst_kmax = 0, worst_share = 1;
  uint32_t seed = 11;
  for (const auto& cap : Captures()) {
    SCOPED_TRACE(cap.name);
    const Outcome r = Measure(cap, seed++, /*with_uncertainty=*/true);
    EXPECT_EQ(r.wrong, 0);
    EXPECT_EQ(r.duplicates, 0);
    if (r.refused) {
      ++refused;
      EXPECT_FALSE(r.reason.empty());
      fmt::print("{}: refused: {}\n", cap.name, r.reason);
      continue;
    }
    const double share = static_cast<double>(r.identified) / r.visible;
    const auto& c = r.comparison;
    fmt::print("{}: {} of {} visible identified ({:.3f}), {} rejected by the surface, adequacy {:.2f}, structured "
               "{:.2f}; axial rms {:.3f} D, dKmax {:+.3f} D over {:.2f} mm\n",
               cap.name, r.identified, r.visible, share, r.surface_outliers, r.adequacy, r.structured, c.axial_rms_D,
               c.kmax_error_D, c.radius_mm);
    EXPECT_GE(share, kLabelledShare);
    EXPECT_LE(c.axial_rms_D, kAxialRmsD);
    EXPECT_LE(std::abs(c.kmax_error_D), kKmaxD);
    worst_axial = std::max(worst_axial, c.axial_rms_D);
    worst_kmax = std::max(worst_kmax, std::abs(c.kmax_error_D));
    worst_share = std::min(worst_share, share);
  }
  fmt::print("refused {}, worst axial rms {:.3f} D, worst |dKmax| {:.3f} D, lowest share {:.3f}\n", refused,
             worst_axial, worst_kmax, worst_share);
  // Regression bounds near today's figures (2026-12-06, their U included): the two post-LASIK captures refused, their
  // axial maps' U reaching 1.02 and 1.92 D at the blend zone (U of Kmax 0.30 and 1.8 D), where their errors were
  // small (axial rms 0.061 and 0.078 D, |dKmax| 0.08 and 0.05 D): the price of refusing the 3 wrong ones of the test
  // below (docs/uncertainty.md, "Refusal"). "paper, everything" is refused too since spots at the lid's margin are
  // judged by their light (shared residual 0.74 x, limit 0.4; it was measured within the limits before, axial rms
  // 0.028 D). Of the others: worst axial rms 0.027 D, worst |dKmax| 0.008 D, lowest identified share 0.990.
  EXPECT_EQ(refused, 3);
  EXPECT_LE(worst_axial, 0.05);
  EXPECT_LE(worst_kmax, 0.06);
  EXPECT_GE(worst_share, 0.97);
}

// Before the measurement's U, 3 of these 7 seeds were accepted with axial rms 0.39, 0.31 and 0.84 D (|dKmax| 1.3,
// 0.9 and 1.8 D): under the adequacy check's 3x, because the spline smooths the blend zone to the noise it sees.
// Their axial maps' U reaches 3.7, 2.9 and 5.3 D: refused now. Measured 2026-12-05: 3 refused by the adequacy check,
// 3 by their U, seed 13 accepted with axial rms 0.116 D and dKmax +0.33 D.
TEST(ClinicalCapture, APostLasikEyeUnderEveryArtefactIsWithinTwiceTheCleanLimitsOrRefused) {
  int refused = 0, refused_for_u = 0, wrong_in_refused = 0;
  for (uint32_t seed = 11; seed < 18; ++seed) {
    SCOPED_TRACE(seed);
    const Outcome r = Measure(PostLasikEverything(), seed, /*with_uncertainty=*/true);
    EXPECT_EQ(r.duplicates, 0);
    if (r.refused) {
      ++refused;
      refused_for_u += r.reason.find("too uncertain") != std::string::npos;
      wrong_in_refused += r.wrong;
      fmt::print("seed {}: refused ({} wrong identities): {}\n", seed, r.wrong, r.reason);
      continue;
    }
    const auto& c = r.comparison;
    fmt::print("seed {}: accepted, axial rms {:.3f} D, dKmax {:+.3f} D\n", seed, c.axial_rms_D, c.kmax_error_D);
    // Acceptance: no wrong identity in a measurement given, and the clinical-capture limits (twice the clean ones).
    EXPECT_EQ(r.wrong, 0);
    EXPECT_LE(c.axial_rms_D, kAxialRmsD);
    EXPECT_LE(std::abs(c.kmax_error_D), kKmaxD);
  }
  // Regression near today's figures: 6 of 7 refused, 3 of them for their U. The refused ones held 4 wrong
  // identities (seeds 11 and 15: faint blobs at the lid's margin taken for hidden spots, a tenth of a spot's light)
  // until a spot with too few ring neighbours was judged by its light all the same: none now.
  EXPECT_EQ(refused, 6);
  EXPECT_EQ(refused_for_u, 3);
  EXPECT_EQ(wrong_in_refused, 0);
}

}  // namespace
}  // namespace topocal::pipeline
