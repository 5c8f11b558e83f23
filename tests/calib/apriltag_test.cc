#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <map>

#include <opencv2/core.hpp>

#include "calib/apriltag_detector.h"
#include "calib/detect.h"
#include "calib/render_target.h"
#include "detection_fixtures.h"

namespace topocal::calib {
namespace {

// The bars for AprilTag grids.
constexpr double kMinTagRate = 0.99;
constexpr double kTagCornerRmsPx = 0.05;

struct Scene {
  const char* name;
  double tilt_x_deg, tilt_y_deg, roll_deg;
};
const Scene kScenes[] = {
    {"straight-on", 0, 0, 4},
    {"tilt-x-30", 30, 0, -3},
    {"tilt-y-30", 0, 30, 6},
};

RenderedView Render(const TargetDescription& target, const Scene& scene, double noise, uint32_t seed,
                    double shift_x_mm = 0) {
  RenderOptions options;
  options.blur_sigma_px = 1.0;
  options.noise_grey = noise;
  options.seed = seed;
  // 6 x 5 tags of 30 mm at 550 mm: tags ~33 px, bit cells ~4 px.
  const auto pose = PoseFacingTarget(target, 550.0, scene.tilt_x_deg, scene.tilt_y_deg, scene.roll_deg, shift_x_mm);
  auto view = RenderTarget(target, testing::TestCamera(), pose, options);
  EXPECT_TRUE(view.has_value());
  return std::move(*view);
}

// One test for all noise levels: each scene is rendered once and seen at every noise level.
TEST(AprilGrid, FindsAllTagsAndRefinesCornersOnAllViewsAndNoiseLevels) {
  const auto target = testing::AprilGrid6x5();
  std::vector<RenderedView> renders;
  uint32_t render_seed = 21;
  for (const Scene& scene : kScenes) renders.push_back(Render(target, scene, 0.0, render_seed++));
  for (const double noise : {0.0, 1.0, 2.0}) {
    SCOPED_TRACE(::testing::Message() << "noise " << noise << " grey levels");
    int tags_expected = 0, tags_found = 0;
    double sum2 = 0;
    int n = 0;
    for (size_t i = 0; i < std::size(kScenes); ++i) {
      const Scene& scene = kScenes[i];
      const RenderedView& view = renders[i];
      ASSERT_EQ(view.corners.size(), 120u) << scene.name;  // the whole grid is in the image
      const auto result =
          DetectTargetDetailed(target, AddSensorNoise(view.irradiance, noise, static_cast<uint32_t>(200 + i)));
      ASSERT_TRUE(result.view.has_value()) << scene.name << ": " << result.message;
      tags_expected += 30;
      tags_found += result.tags_detected;
      int unmatched = 0;
      const auto stats = testing::CornerError(*result.view, view.corners, &unmatched);
      EXPECT_EQ(unmatched, 0);
      sum2 += stats.rms_px * stats.rms_px * stats.matched;
      n += stats.matched;
      std::printf("noise %.0f %-12s %s, corner RMS %.4f (max %.4f) px\n", noise, scene.name, result.message.c_str(),
                  stats.rms_px, stats.max_px);
    }
    const double rms = std::sqrt(sum2 / n);
    std::printf("noise %.0f all views: %d/%d tags, corner RMS %.4f px\n", noise, tags_found, tags_expected, rms);
    EXPECT_GE(tags_found, kMinTagRate * tags_expected);
    EXPECT_LT(rms, kTagCornerRmsPx);
    // Regression bound: measured 2026-12-02 0.0232, 0.0296 and 0.0414 px at noise 0, 1 and 2 grey levels (seeded
    // renders); about 20 % above each, the acceptance being near.
    constexpr double kRegressionRmsPx[] = {0.028, 0.036, 0.048};
    EXPECT_LT(rms, kRegressionRmsPx[static_cast<int>(noise)]);
  }
}

// libapriltag's own corners (refinement off), converted with kAprilTagToOpenCvOffsetPx, must be centred on the
// truth; the opposite sign would leave a mean offset of 1 px on both axes, no conversion 0.5 px.
TEST(AprilGrid, HalfPixelConventionIsConverted) {
  const auto target = testing::AprilGrid6x5();
  const RenderedView view = Render(target, kScenes[0], 0.0, 5);
  DetectionOptions raw;
  raw.refinement = CornerRefinement::kNone;
  const auto found = DetectTarget(target, view.image, raw);
  ASSERT_TRUE(found.has_value());
  std::map<int, Eigen::Vector2d> truth;
  for (const auto& t : view.corners) truth[t.id] = t.image_px;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& c : found->corners) mean += c.image_px - truth.at(c.id);
  mean /= static_cast<double>(found->corners.size());
  std::printf("libapriltag corners after the %+.1f px conversion: mean offset (%.3f, %.3f) px\n",
              kAprilTagToOpenCvOffsetPx, mean.x(), mean.y());
  // libapriltag's edge refinement scatters corners by ~0.1 px; their mean over 120 corners is within a tenth of a
  // pixel, far from the 0.5 px step this test tells apart.
  constexpr double kMeanOffsetTolPx = 0.1;
  EXPECT_LT(std::abs(mean.x()), kMeanOffsetTolPx);
  EXPECT_LT(std::abs(mean.y()), kMeanOffsetTolPx);
  // Regression bound: measured 2026-12-02 (-0.002, -0.005) px; 0.02 px is 4x the larger.
  EXPECT_LT(mean.norm(), 0.02);
}

TEST(AprilGrid, PartialViewsKeepTheirIds) {
  const auto target = testing::AprilGrid6x5();
  const RenderedView view = Render(target, kScenes[1], 1.0, 6, 260.0);
  ASSERT_LT(view.corners.size(), 120u);
  const auto result = DetectTargetDetailed(target, view.image);
  ASSERT_TRUE(result.view.has_value()) << result.message;
  EXPECT_GT(result.tags_detected, 10);
  EXPECT_LT(result.tags_detected, 30);
  int unmatched = 0;
  const auto stats = testing::CornerError(*result.view, view.corners, &unmatched);
  std::printf("partial view at the image edge: %d tags, corner RMS %.4f (max %.4f) px\n", result.tags_detected,
              stats.rms_px, stats.max_px);
  EXPECT_EQ(unmatched, 0);
  // Ids are right when every corner lies within a fraction of the ~4 px bit cell of its truth (a wrong id is a
  // whole cell or tag away). Accuracy at the image edge, tilted, is reported, not held to the straight-on bar.
  constexpr double kSameCornerPx = 0.5;
  EXPECT_LT(stats.max_px, kSameCornerPx);
}

TEST(AprilGrid, TagsOfAnotherGridAreRejected) {
  // The same layout printed from id 100: none of its ids is on a grid starting at 0.
  const auto other = ParseTargetDescription(
      "target_type: aprilgrid\ntagCols: 6\ntagRows: 5\ntagSize: 0.03\ntagSpacing: 0.3\nfirstTagId: 100\n"
      "tagBorderBits: 1\n",
      "other");
  const RenderedView view = Render(other, kScenes[0], 0.0, 7);
  const auto result = DetectTargetDetailed(testing::AprilGrid6x5(), view.image);
  EXPECT_FALSE(result.view.has_value());
  EXPECT_EQ(result.tags_rejected, 30);
  EXPECT_TRUE(DetectTarget(other, view.image).has_value());
}

// Detections of a 6 x 6 grid seen obliquely through a lens with strong barrel distortion (the border pulled in by
// ~4 % of the image), as the detectors hand them to FinishAprilGridDetections; `misread` (if set) carries the id of a
// tag that is not in the image.
AprilGridDetections SyntheticDetections(const AprilGridLayout& grid, std::optional<int> misread = std::nullopt) {
  AprilGridDetections d;
  const double f = 900, cx = 640, cy = 480, k1 = -0.25;
  for (int t = 0; t < grid.NumTags(); ++t) {
    if (t == 35) continue;  // out of view: its id is the misread one's
    TagDetection tag;
    tag.tag_index = misread && t == 14 ? *misread : t;
    const Eigen::Vector2d origin = grid.TagOriginMm(t);
    const double dx[4] = {0, grid.tag_size_mm, grid.tag_size_mm, 0}, dy[4] = {grid.tag_size_mm, grid.tag_size_mm, 0, 0};
    for (int k = 0; k < 4; ++k) {
      // The board 500 mm away, turned 25 deg about y, centred on the axis; then Brown k1 on normalised coordinates.
      const double x = origin.x() + dx[k] - 125, y = origin.y() + dy[k] - 125;
      const double c = std::cos(25 * M_PI / 180), s = std::sin(25 * M_PI / 180);
      const double X = c * x, Z = 500 + s * x;
      const double u = X / Z, v = y / Z, r2 = u * u + v * v;
      tag.corners_px[static_cast<size_t>(k)] = {cx + f * u * (1 + k1 * r2), cy + f * v * (1 + k1 * r2)};
    }
    d.tags.push_back(tag);
  }
  return d;
}

TEST(AprilGrid, ATagNotWhereItsNeighboursPutItsIdIsLeftOutWithTheReason) {
  AprilGridLayout grid;
  grid.tag_cols = grid.tag_rows = 6;
  grid.tag_size_mm = 40;
  grid.tag_spacing_ratio = 0.3;
  // Every tag where the grid puts it: none is dropped, whatever the distortion.
  auto clean = SyntheticDetections(grid);
  FinishAprilGridDetections(grid, &clean);
  EXPECT_EQ(clean.tags.size(), 35u) << (clean.reasons.empty() ? "" : clean.reasons.front());
  EXPECT_EQ(clean.rejected, 0);
  // Tag 14 read as 35 (a tag out of view): the one tag left out, named, its neighbours kept.
  auto misread = SyntheticDetections(grid, 35);
  FinishAprilGridDetections(grid, &misread);
  ASSERT_EQ(misread.tags.size(), 34u);
  EXPECT_EQ(misread.rejected, 1);
  for (const auto& tag : misread.tags) EXPECT_NE(tag.tag_index, 35);
  ASSERT_EQ(misread.reasons.size(), 1u);
  EXPECT_NE(misread.reasons[0].find("tag id 35"), std::string::npos) << misread.reasons[0];
  EXPECT_NE(misread.reasons[0].find("misread"), std::string::npos) << misread.reasons[0];
}

TEST(AprilGrid, NoGridIsNotFoundWithoutCrashing) {
  const auto target = testing::AprilGrid6x5();
  cv::Mat blank(480, 640, CV_8UC1, cv::Scalar(200));
  EXPECT_FALSE(DetectTarget(target, blank).has_value());
  cv::Mat noise(240, 320, CV_8UC1);
  cv::randu(noise, 0, 255);
  EXPECT_FALSE(DetectTarget(target, noise).has_value());
  cv::Mat tiny(3, 3, CV_8UC1, cv::Scalar(0));
  EXPECT_FALSE(DetectTarget(target, tiny).has_value());
  // A checkerboard is not an AprilTag grid.
  const auto board = testing::Checkerboard9x6();
  const auto view = RenderTarget(board, testing::TestCamera(), PoseFacingTarget(board, 420.0), RenderOptions{});
  ASSERT_TRUE(view.has_value());
  EXPECT_FALSE(DetectTarget(target, view->image).has_value());
}

}  // namespace
}  // namespace topocal::calib
