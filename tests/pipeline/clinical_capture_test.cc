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
#include <optional>
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
#include "tests/correct/capture_eyes.h"
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

// A capture rendered through a drawn device, with the visible spots' true (distorted) positions.
struct Rendered {
  model::Device device;
  cv::Mat image;
  std::map<model::SpotId, Eigen::Vector2d> where_mm;
};

Rendered RenderCapture(const Capture& cap, uint32_t seed, const model::Config& cfg = testing::PaperConfig()) {
  std::mt19937 rng(seed);
  Rendered r;
  r.device = testing::DrawDevice(rng);
  const model::Device& device = r.device;
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
  r.image = correct::RenderSpotImage(spots, device.camera.width_px, device.camera.height_px, o);
  for (const auto& s : spots) {
    if (s.id.ring != 0) r.where_mm[s.id] = device.camera.DetectionPlaneFromPixel(s.centre_px);
  }
  return r;
}

// Whether the visible spot nearest to a detection at `mm` is another than `id` (a right identity whose centre a lash
// pulled by a few px is still nearest to its own spot, ~20 px from the next).
bool WrongIdentity(const std::map<model::SpotId, Eigen::Vector2d>& where_mm, const model::SpotId& id,
                   const Eigen::Vector2d& mm) {
  model::SpotId nearest;
  double best = std::numeric_limits<double>::infinity();
  for (const auto& [truth_id, truth_mm] : where_mm) {
    if ((truth_mm - mm).norm() < best) {
      best = (truth_mm - mm).norm();
      nearest = truth_id;
    }
  }
  return !(nearest == id);
}

// with_uncertainty: also the U of the measurement (the spots' measured noise; the drawn device is exact here, so it
// has no covariance) and the refusal of a map too uncertain for a clinical reading (UncertaintyRefusal).
Outcome Measure(const Capture& cap, uint32_t seed, bool with_uncertainty = false) {
  const auto cfg = testing::PaperConfig();
  const Rendered rendered = RenderCapture(cap, seed);
  const model::Device& device = rendered.device;
  const cv::Mat& image = rendered.image;
  const auto& where_mm = rendered.where_mm;
  Outcome out;
  out.visible = static_cast<int>(where_mm.size());
  SpotMeasurement m;
  try {
    m = MeasureSpots(image, device, cfg.ideal_image);
  } catch (const util::MeasurementRefused& e) {
    out.refused = true;
    out.reason = e.what();
    return out;
  }
  const auto config = ForEyes(cfg);  // as `reconstruct` measures eyes
  topo::Analysis analysis;
  MeasurementVerdict verdict = LabelAndJudge(&m, device, config, AnalysisOf(&device, config, nullptr), &analysis);
  out.identified = m.capture.identified;
  for (const auto& d : m.detected) out.wrong += WrongIdentity(where_mm, d.id, d.position_mm);
  std::set<model::SpotId> ids;
  for (const auto& d : m.detected) ids.insert(d.id);
  out.duplicates = static_cast<int>(m.detected.size() - ids.size());
  out.surface_outliers = static_cast<int>(m.capture.surface_outliers.size());
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

// `topocal detect` and the Python module's detect() give the identities the measurement uses (DetectThroughSurface):
// on post-LASIK eyes under a lid and other artefacts the spots the surface rejected are flagged surface_outlier and
// left out, the usable identities are the measurement's, each right, and the verdict is the measurement's.
TEST(ClinicalCapture, DetectionGivesTheIdentitiesTheMeasurementUses) {
  // The deep myopic ablation, decentred, where the lattice leaves a ring of the blend zone to the surface.
  const auto eyes = correct::testing::Eyes();
  const Capture deep{"lasik-myopic-8D decentred, upper lid 20 %", eyes.back().surface, 0.2, 0.0, 8000, {}};
  const auto config = ForEyes(testing::PaperConfig());
  int rejected_total = 0;
  for (const auto& [cap, seed] : {std::pair{PostLasikEverything(), 13u}, std::pair{PostLasikEverything(), 11u},
                                  std::pair{deep, 17u}, std::pair{deep, 19u}}) {
    SCOPED_TRACE(fmt::format("{}, seed {}", cap.name, seed));
    const Rendered r = RenderCapture(cap, seed);
    const CheckedSpots checked =
        DetectThroughSurface(r.image, r.device, /*undistort=*/true, AnalysisOf(&r.device, config, nullptr), config);
    SpotMeasurement m = MeasureSpots(r.image, r.device, config.ideal_image);
    topo::Analysis analysis;
    const auto verdict = LabelAndJudge(&m, r.device, config, AnalysisOf(&r.device, config, nullptr), &analysis);
    EXPECT_EQ(checked.verdict.valid, verdict.valid);
    // The usable identities are the measurement's, at the same positions.
    const std::set<model::SpotId> outliers(m.capture.surface_outliers.begin(), m.capture.surface_outliers.end());
    std::set<std::pair<model::SpotId, std::pair<double, double>>> measured, detected;
    for (const auto& d : m.detected) {
      if (!outliers.count(d.id)) measured.insert({d.id, {d.position_mm.x(), d.position_mm.y()}});
    }
    for (const auto& s : checked.located.spots) detected.insert({s.id, {s.position_mm.x(), s.position_mm.y()}});
    EXPECT_EQ(detected, measured);
    // Every identity right, the flagged spots' too: before their identities were checked against the surface
    // (CheckFlaggedIdentities), 1, 1, 0 and 2 of them here were another spot's (centres a lid's margin pulled).
    int labelled = 0, rejected = 0, wrong = 0, wrong_flagged = 0;
    for (const auto& s : checked.located.spots) wrong += WrongIdentity(r.where_mm, s.id, s.position_mm);
    for (const auto* list : {&checked.located.spots, &checked.located.excluded}) {
      for (const auto& s : *list) {
        labelled += (s.flags & correct::kSurfaceLabelled) != 0;
        rejected += (s.flags & correct::kSurfaceOutlier) != 0;
      }
    }
    for (const auto& s : checked.located.excluded) wrong_flagged += WrongIdentity(r.where_mm, s.id, s.position_mm);
    fmt::print("{}, seed {}: {} identified through the surface, {} rejected by it, {} wrong usable, {} wrong flagged, "
               "{} flagged identities dropped; verdict {}\n",
               cap.name, seed, labelled, rejected, wrong, wrong_flagged, checked.flagged_identities_dropped,
               verdict.valid ? "valid" : verdict.reasons.front());
    if (checked.verdict.valid) {
      EXPECT_EQ(wrong_flagged, 0);
    }
    EXPECT_EQ(labelled, m.capture.surface_labelled);
    EXPECT_EQ(rejected, static_cast<int>(outliers.size()));
    EXPECT_EQ(wrong, 0);
    rejected_total += rejected;
    std::set<model::SpotId> ids;
    for (const auto* list : {&checked.located.spots, &checked.located.excluded}) {
      for (const auto& s : *list) EXPECT_TRUE(ids.insert(s.id).second) << "twice: " << s.id.ring << "," << s.id.index;
    }
    for (const auto& id : checked.located.missing) EXPECT_FALSE(ids.count(id)) << id.ring << "," << id.index;
    EXPECT_EQ(checked.located.spots.size() + checked.located.excluded.size() + checked.located.missing.size(),
              static_cast<size_t>(m.capture.designed));
  }
  EXPECT_GT(rejected_total, 0);  // the cases show the surface's check at work (measured: 15, 26, 59, 76)
}

// The paper's screen and the one `topocal design --optimize` chooses from exact spots (docs/screen-design.md: 26
// rings x 6, spots of 2.70 um that leave 4.5 px between neighbouring spot images on the goal's ablations, the
// spline's knots every 0.15 mm; these renders' spot centres carry 0.001-0.002 px of noise), side by side on noisy
// images of post-LASIK eyes from -8 to +6 D and keratoconus cones: rendered through a drawn device (read noise
// 60 DN, shot noise at 4 e-/DN), detected, identified and reconstructed as `reconstruct --image --device` does.
struct ScreenOutcome {
  bool refused = false;
  std::string reason;
  int wrong = 0, identified = 0, visible = 0;
  double centre_rms_px = 0;  // detected centres against the rendered truth, each coordinate, right identities
  topo::TruthComparison comparison;
};

ScreenOutcome MeasureOnScreen(const Capture& cap, uint32_t seed, const model::Config& config) {
  const Rendered r = RenderCapture(cap, seed, config);
  ScreenOutcome out;
  out.visible = static_cast<int>(r.where_mm.size());
  SpotMeasurement m;
  try {
    m = MeasureSpots(r.image, r.device, config.ideal_image);
  } catch (const util::MeasurementRefused& e) {
    out.refused = true;
    out.reason = e.what();
    return out;
  }
  topo::Analysis analysis;
  const auto verdict = LabelAndJudge(&m, r.device, config, AnalysisOf(&r.device, config, nullptr), &analysis);
  for (const auto& d : m.detected) out.wrong += WrongIdentity(r.where_mm, d.id, d.position_mm);
  double squared_px = 0;
  int compared = 0;
  for (const auto& d : m.detected) {
    const auto truth = r.where_mm.find(d.id);
    if (truth == r.where_mm.end()) continue;
    squared_px += ((d.position_mm - truth->second) / r.device.camera.PitchMm()).squaredNorm();
    ++compared;
  }
  if (compared > 0) out.centre_rms_px = std::sqrt(squared_px / (2.0 * compared));
  out.identified = m.capture.identified;
  out.refused = !verdict.valid;
  if (out.refused) out.reason = verdict.reasons.front();
  try {
    out.comparison = topo::CompareWithTruth(analysis, cap.eye, config.reconstruction);
  } catch (const std::exception&) {
    if (!out.refused) throw;  // a refused measurement may have no map to compare
  }
  return out;
}

TEST(ClinicalCapture, ADesignedScreenResolvesTheAblationsThePapersCannot) {
  const auto paper = ForEyes(testing::PaperConfig());
  model::Config designed = paper;
  designed.ideal_image = correct::testing::DesignedScreen(designed.ideal_image);
  designed.reconstruction.surface_model = "spline";
  designed.reconstruction.surface_model_given = true;
  designed.reconstruction.spline_spacing_mm = 0.15;
  std::vector<Capture> caps;
  for (const char* name : {"lasik-myopic-4D", "lasik-hyperopic-4D"}) {
    caps.push_back({name, Freeform(name), 0, 0, 0, {}});
  }
  for (const auto& e : correct::testing::Eyes()) {
    if (e.name.rfind("lasik", 0) == 0 || e.name.rfind("kc-33", 0) == 0 || e.name.rfind("kc-60", 0) == 0) {
      caps.push_back({e.name, e.surface, 0, 0, 0, {}});
    }
  }
  uint32_t seed = 31;
  double worst_tangential = 0, worst_axial = 0, worst_centre_px = 0;
  int designed_refused = 0, within_tangential_target = 0;
  for (const auto& cap : caps) {
    SCOPED_TRACE(cap.name);
    const ScreenOutcome p = MeasureOnScreen(cap, seed, paper);
    const ScreenOutcome d = MeasureOnScreen(cap, seed, designed);
    ++seed;
    for (const auto* o : {&p, &d}) {
      fmt::print("{:<30} {:<8} {} of {} identified, {} wrong, centres {:.4f} px rms; {}; axial rms {:.3f} D, "
                 "tangential rms {:.3f} D\n",
                 cap.name, o == &p ? "paper" : "designed", o->identified, o->visible, o->wrong, o->centre_rms_px,
                 o->refused ? "refused: " + o->reason.substr(0, 60) : "valid", o->comparison.axial_rms_D,
                 o->comparison.tangential_rms_D);
      EXPECT_EQ(o->wrong, 0);  // acceptance: indexing still right, whatever the screen
    }
    if (d.refused) {
      ++designed_refused;
      continue;
    }
    EXPECT_EQ(d.identified, d.visible);
    EXPECT_LT(d.comparison.tangential_rms_D, p.comparison.tangential_rms_D);
    worst_centre_px = std::max(worst_centre_px, d.centre_rms_px);
    within_tangential_target += d.comparison.tangential_rms_D <= 0.25;
    worst_tangential = std::max(worst_tangential, d.comparison.tangential_rms_D);
    worst_axial = std::max(worst_axial, d.comparison.axial_rms_D);
  }
  fmt::print("designed screen: worst axial rms {:.3f} D, worst tangential rms {:.3f} D, centres {:.4f} px, "
             "{} refused\n", worst_axial, worst_tangential, worst_centre_px, designed_refused);
  // Acceptance: axial rms <= 0.1 D; the tangential 0.25 D holds on all but the deepest myopic ablation, which
  // is decentred. Measured 2026-12-07: myopic -4 / -6 / -8 D 0.128 / 0.200 / 0.278 D, hyperopic +4 / +6 D 0.134 /
  // 0.222 D, the 33 um cone 0.052 D, the severe decentred 60 um cone 0.055 D; worst axial rms 0.016 D; centres
  // 0.0017-0.0020 px from the truth (the paper's lone 8 um spots: 0.0012-0.0016 px; the same screen with 4.34 um
  // spots, 2.5 px apart on the -6 D blend: 0.0048-0.0138 px and 0.266 / 0.339 D on the -6 / -8 D ablations). The
  // paper's screen: 0.8-1.9 D on the ablations, four of the six refused by the surface model's adequacy check. The
  // 60 um cone shears the designed screen's inner rings: it is identified from a stretched start (before the
  // matcher searched them, it was refused).
  EXPECT_LE(worst_axial, 0.1);
  EXPECT_LE(worst_axial, 0.025);
  EXPECT_EQ(within_tangential_target, 6);  // of the seven measured
  EXPECT_LE(worst_tangential, 0.30);
  EXPECT_LE(worst_centre_px, 0.0025);
  EXPECT_EQ(designed_refused, 0);
}

// The severe decentred 60 um cone on the screens `design --optimize` weighs (spot radii as its table gives them,
// knots every 0.2 mm), rendered noisy as above: on each, the identities are right, or the measurement is refused.
TEST(ClinicalCapture, TheSevereDecentredConeIsReadOrRefusedOnEveryCandidateScreen) {
  const auto paper = ForEyes(testing::PaperConfig());
  std::optional<Capture> cap;
  for (const auto& e : correct::testing::Eyes()) {
    if (e.name.rfind("kc-60", 0) == 0) cap = Capture{e.name, e.surface, 0, 0, 0, {}};
  }
  ASSERT_TRUE(cap);
  struct Screen {
    int rings, eta;
    double spot_radius_um;
  };
  int right = 0;
  for (const Screen s : {Screen{12, 6, 8.0}, Screen{16, 6, 6.97}, Screen{22, 6, 3.90}, Screen{22, 8, 3.3},
                         Screen{12, 8, 8.0}, Screen{16, 8, 5.64}, Screen{26, 6, 2.70}}) {
    SCOPED_TRACE(fmt::format("{} x {}", s.rings, s.eta));
    model::Config c = paper;
    c.ideal_image.rings_N = s.rings - 1;
    c.ideal_image.eta0 = c.ideal_image.eta = s.eta;
    c.ideal_image.spot_radius_um = s.spot_radius_um;
    c.reconstruction.surface_model = "spline";
    c.reconstruction.surface_model_given = true;
    c.reconstruction.spline_spacing_mm = 0.2;
    const ScreenOutcome o = MeasureOnScreen(*cap, 36, c);
    fmt::print("{} x {}: {} of {} identified, {} wrong; {}\n", s.rings, s.eta, o.identified, o.visible, o.wrong,
               o.refused ? "refused: " + o.reason : "valid");
    if (o.wrong > 0) EXPECT_TRUE(o.refused);  // acceptance: a wrong identity never gives a reading
    right += o.wrong == 0 && o.identified == o.visible;
  }
  // Measured 2026-12-07: every identity right on all seven. Before the matcher searched stretched starts: on two of
  // seven (12 x 8, 16 x 8), the others refused; on 16 x 6 the isotropic start grew a lattice a spot off (375
  // identities, all wrong) that only the surface refused, until a lattice explaining under 3/4 of the detections
  // made the matcher try the stretched starts too.
  EXPECT_EQ(right, 7);
}

}  // namespace
}  // namespace topocal::pipeline
