// Spot detection: sub-pixel centres against the renderer's truth, both centroid methods, PSF and ellipse spots.
#include "correct/spot_detect.h"

#include <cmath>
#include <iostream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "correct/detect_and_index.h"
#include "correct/spot_render.h"
#include "synthetic.h"
#include "util/io.h"

namespace topocal::correct {
namespace {

// Acceptance: spot centroids within 0.02 px RMS of the truth at realistic noise.
constexpr double kCentroidRmsPx = 0.02;
// Regression bounds per method, about 2x the worst rms over the four scenes measured 2026-12-02 (seeded renders):
// intensity-weighted 0.0046 px, weighted PSF fit 0.0024 px. The Gaussian fit measures up to 0.019 px on the
// elliptical spots, near the acceptance, which therefore bounds it alone.
double RegressionRmsPx(CentroidMethod method) {
  switch (method) {
    case CentroidMethod::kIntensityWeighted:
      return 0.01;
    case CentroidMethod::kWeightedPsfFit:
      return 0.005;
    default:
      return kCentroidRmsPx;
  }
}
// A detection is matched to the truth spot within this distance; far above any centroid error, far below the
// ~16 px spot spacing.
constexpr double kMatchPx = 3.0;

// A 1000 x 1000 crop of the default camera about its principal point: holds the whole pattern (about +-400 px),
// renders in a fraction of the full sensor's time.
model::TopographerCamera CropCamera() {
  auto c = testing::DefaultCamera();
  c.width_px = 1000;
  c.height_px = 1000;
  c.principal_point_px = {499.5, 499.5};
  return c;
}

// Realistic noise for a 16-bit frame: spot level 40000 DN over 1000 DN background, 60 DN read noise and shot noise
// at 4 e-/DN (about 100 DN at the spot level): a peak SNR of ~340, a well-exposed 12-bit-class sensor.
SpotRenderOptions Realistic(SpotShape shape, double psf_px) {
  SpotRenderOptions o;
  o.shape = shape;
  o.psf_sigma_px = psf_px;
  o.bits = 16;
  o.background_dn = 1000;
  o.peak_dn = 40000;
  o.read_noise_dn = 60;
  o.gain_e_per_dn = 4;
  o.seed = 7;
  return o;
}

struct Errors {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  double rms = 0;
  int matched = 0;
};

Errors Compare(const std::vector<DetectedSpot>& found, const std::vector<SpotToRender>& truth) {
  Errors e;
  for (const auto& t : truth) {
    const DetectedSpot* best = nullptr;
    double best_d = kMatchPx;
    for (const auto& f : found) {
      const double d = (f.centre_px - t.centre_px).norm();
      if (d < best_d) {
        best_d = d;
        best = &f;
      }
    }
    if (!best) continue;
    const Eigen::Vector2d err = best->centre_px - t.centre_px;
    e.mean += err;
    e.rms += err.squaredNorm();
    ++e.matched;
  }
  if (e.matched > 0) {
    e.mean /= e.matched;
    e.rms = std::sqrt(e.rms / e.matched);
  }
  return e;
}

struct Scene {
  std::string name;
  SpotShape shape;
  double psf_px;
  double sigma;
};

class SpotDetect : public ::testing::TestWithParam<Scene> {};

TEST_P(SpotDetect, CentroidsWithinTwoHundredthsOfAPixel) {
  const auto cfg = testing::PaperConfig();
  const auto camera = CropCamera();
  const auto& scene = GetParam();
  const auto truth = testing::Truth(cfg, cfg.cornea, scene.sigma, camera);
  const cv::Mat image = RenderSpotImage(truth.spots, camera.width_px, camera.height_px, Realistic(scene.shape, scene.psf_px));
  for (const auto method :
       {CentroidMethod::kIntensityWeighted, CentroidMethod::kGaussianFit, CentroidMethod::kWeightedPsfFit}) {
    SpotDetectionOptions o;
    o.method = method;
    const auto det = DetectSpots(image, o);
    const auto e = Compare(det.spots, truth.spots);
    const char* name = CentroidMethodName(method);
    std::cout << scene.name << " " << name << ": matched " << e.matched << "/" << truth.spots.size() << ", bias ("
              << e.mean.x() << ", " << e.mean.y() << ") px, rms " << e.rms << " px\n";
    EXPECT_EQ(e.matched, static_cast<int>(truth.spots.size())) << name;
    EXPECT_EQ(det.spots.size(), truth.spots.size()) << name;
    EXPECT_LT(e.rms, kCentroidRmsPx) << name;
    EXPECT_LT(e.rms, RegressionRmsPx(method)) << name;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, SpotDetect,
    ::testing::Values(Scene{"psf1.5", SpotShape::kPsf, 1.5, 0.0}, Scene{"ellipse", SpotShape::kEllipse, 1.0, 0.0},
                      Scene{"ellipse-barrel", SpotShape::kEllipse, 1.0, 2e-4},
                      Scene{"ellipse-pincushion", SpotShape::kEllipse, 1.0, -2e-4}),
    [](const auto& test_info) {
      std::string n = test_info.param.name;
      for (auto& c : n) c = std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
      return n;
    });

// An 8-bit frame: background 10 DN, spots 200 DN above it, read noise 1.5 DN, no shot noise.
SpotRenderOptions EightBit() {
  SpotRenderOptions o = Realistic(SpotShape::kEllipse, 1.0);
  o.bits = 8;
  o.background_dn = 10;
  o.peak_dn = 200;
  o.read_noise_dn = 1.5;
  o.gain_e_per_dn = 0;
  return o;
}

// Two defocused spots (PSF 2.5 px) 9 px apart merge above the threshold (the saddle at 40 % of their level): the
// detector splits them at a second threshold and measures both — the "every sensor measures all its spots".
// Each is fitted in its share of the gap, the neighbour's tail in it unmodelled: measured 2026-12-03, 0.14 and
// 0.24 px from the truth (docs/spot-noise.md, "Close neighbours": fitting the pair jointly is not done). The bound
// is a regression bound near that.
TEST(SpotDetect, TwoMergedSpotsAreSplitAndBothMeasured) {
  SpotRenderOptions o = Realistic(SpotShape::kPsf, 2.5);
  std::vector<SpotToRender> spots(2);
  spots[0].id = {1, 0};
  spots[0].centre_px = {40.3, 50.2};
  spots[1].id = {1, 1};
  spots[1].centre_px = {49.3, 50.7};
  const cv::Mat image = RenderSpotImage(spots, 100, 100, o);
  cv::Mat mask;
  cv::compare(image, 1000 + 0.25 * 40000, mask, cv::CMP_GT);
  cv::Mat labels;
  ASSERT_EQ(cv::connectedComponents(mask, labels), 2) << "the two spots must touch above the threshold";
  const auto det = DetectSpots(image);
  ASSERT_EQ(det.spots.size(), 2u);
  for (const auto& t : spots) {
    double best = 1e9;
    for (const auto& d : det.spots) best = std::min(best, (d.centre_px - t.centre_px).norm());
    EXPECT_LT(best, 0.3);
  }
}

// The raw-image entry point end to end: drops and glints, 8-bit, every spot identified correctly.
TEST(DetectAndIndex, RawImageWithDropsAndGlints) {
  const auto cfg = testing::PaperConfig();
  const auto camera = CropCamera();
  const auto truth = testing::Truth(cfg, cfg.cornea, 6.3e-5, camera);
  const auto spots = DropAndAddGlints(truth.spots, 0.10, 5, 14.0, 3);
  SpotRenderOptions o = EightBit();
  const cv::Mat image = RenderSpotImage(spots, camera.width_px, camera.height_px, o);
  const auto r = DetectAndIndexSpots(image, camera, cfg.ideal_image);
  ASSERT_TRUE(r.ok) << r.message;
  int real = 0;
  for (const auto& s : spots) real += s.id.ring != 0;
  // Identified: the usable spots and those flagged near a glint (kept out of a measurement, identity still given).
  EXPECT_EQ(static_cast<int>(r.spots.size() + r.excluded.size()), real);
  EXPECT_EQ(r.unassigned.size(), 5u);
  for (const auto& s : r.excluded) EXPECT_TRUE(s.flags & kNearBlob) << SpotFlagsText(s.flags);
  auto identified = r.spots;
  identified.insert(identified.end(), r.excluded.begin(), r.excluded.end());
  for (const auto& s : identified) {
    // The truth spot with this identity must be where the detection is.
    const auto it = std::find_if(spots.begin(), spots.end(), [&](const auto& t) { return t.id == s.id; });
    ASSERT_NE(it, spots.end());
    EXPECT_LT((it->centre_px - s.position_px).norm(), kMatchPx);
    EXPECT_LT((camera.PixelFromDetectionPlane(s.position_mm) - s.position_px).norm(), 1e-9);
  }
}

// An upper lid with its skin drawn (35 DN above an 8-bit background of 10, textured +-9 DN at two scales, over a
// third of the frame): the skin widens the histogram (its MAD read 24 DN of noise where the read noise is 1.5) and
// lifts the background under part of the pattern. The noise from neighbouring-pixel differences and the local
// background keep the skin out and every identity right.
TEST(DetectAndIndex, ALidsTexturedSkinGivesNoSpuriousBlobs) {
  const auto cfg = testing::PaperConfig();
  const auto camera = CropCamera();
  const auto truth = testing::Truth(cfg, cfg.cornea, 6.3e-5, camera);
  SpotRenderOptions o = EightBit();
  o.lids = LidsOver(truth.spots, 0.3, 0.0);
  o.skin_dn = 35;
  o.skin_texture_dn = 9;
  const auto spots = HideUnderLids(truth.spots, o.lids);
  const cv::Mat image = RenderSpotImage(spots, camera.width_px, camera.height_px, o);
  SpotDetectionOptions global_only;
  global_only.local_background = false;
  const auto before = DetectSpots(image, global_only);
  const auto r = DetectAndIndexSpots(image, camera, cfg.ideal_image);
  ASSERT_TRUE(r.ok) << r.message;
  fmt::print("skin: {} detections with the global threshold alone, {} with the local background ({} spots); noise "
             "{:.2f} DN; {} of {} identified\n",
             before.spots.size(), r.detection.spots.size(), spots.size(), r.detection.noise_dn,
             r.spots.size() + r.excluded.size(), spots.size());
  EXPECT_LE(r.unassigned.size(), 3u);
  auto identified = r.spots;
  identified.insert(identified.end(), r.excluded.begin(), r.excluded.end());
  EXPECT_GE(identified.size(), spots.size() * 95 / 100);
  for (const auto& s : identified) {
    const auto it = std::find_if(spots.begin(), spots.end(), [&](const auto& t) { return t.id == s.id; });
    ASSERT_NE(it, spots.end());
    EXPECT_LT((it->centre_px - s.position_px).norm(), kMatchPx);
  }
}

TEST(SpotDetectOptions, InvalidOptionsSayWhy) {
  SpotDetectionOptions o;
  o.min_area_px = 0;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("min_area_px"), std::string::npos);
  EXPECT_THROW(DetectSpots(cv::Mat(10, 10, CV_8UC3), {}), util::InputError);
}

}  // namespace
}  // namespace topocal::correct
