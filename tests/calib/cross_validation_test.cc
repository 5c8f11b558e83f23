// Cross-validation (calib/cross_validation.h): the model difference removes a homography and nothing else; two
// halves of a seeded synthetic set agree to the noise.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "calib/cross_validation.h"
#include "synthetic_views.h"

namespace topocal::calib {
namespace {

double Rms(const std::vector<ModelDifferenceSample>& samples) {
  double sum2 = 0;
  for (const auto& s : samples) sum2 += s.difference_px * s.difference_px;
  return std::sqrt(sum2 / static_cast<double>(samples.size()));
}

TEST(ModelDifference, RemovesAHomographyButNotADistortionChange) {
  const model::CameraModel a = testing::ReferenceCamera();
  // Identical models: only findHomography's Levenberg-Marquardt stop remains (measured 1.9e-7 px on 2026-12-01).
  constexpr double kIdenticalFloorPx = 1e-6;
  EXPECT_LT(Rms(ModelDifference(a, a)), kIdenticalFloorPx);
  // Without distortion, another focal length and principal point is a homography of the rays: no difference.
  model::CameraModel pinhole = a;
  pinhole.dist = {};
  model::CameraModel moved = pinhole;
  moved.fx_px *= 1.01;
  moved.fy_px *= 0.995;
  moved.cx_px += 4.0;
  moved.cy_px -= 3.0;
  // findHomography's refinement stops at ~1e-8 of the normalised coordinates (~1e-5 px).
  constexpr double kHomographyFloorPx = 1e-4;
  EXPECT_LT(Rms(ModelDifference(pinhole, moved)), kHomographyFloorPx);
  // A change of k1 by 0.01 moves the image corners (r ~ 0.75 normalised) by ~ 0.01 * 0.42 * 540 = 2 px; a
  // homography takes up part of it, not all.
  model::CameraModel distorted = a;
  distorted.dist[0] += 0.01;
  const auto samples = ModelDifference(a, distorted);
  ASSERT_EQ(samples.size(), 40u * 30u);
  const double rms = Rms(samples);
  std::printf("k1 + 0.01: RMS difference %.3f px\n", rms);
  EXPECT_GT(rms, 0.1);
}

TEST(CrossValidation, HalvesOfAGoodSetAgreeToTheNoise) {
  const testing::GridTarget grid;
  const model::CameraModel truth = testing::ReferenceCamera();
  std::mt19937 rng(7);
  std::vector<ViewObservations> views;
  // Sixteen views, interleaved: each reference pose, then a variant of it (turned and moved), so that each half
  // holds a complete, well-spread set of eight; independent noise of 0.1 px per axis.
  const auto poses = testing::ReferencePoses(grid);
  const double variant[8][6] = {{25, 5, 10, 15, -10, 480},  {-25, 0, -8, -15, 10, 440}, {5, 30, 6, 20, -5, 470},
                                {0, -30, -6, -20, 5, 430},  {20, 20, 12, -10, 10, 510}, {-20, -20, 4, 10, -10, 410},
                                {30, -5, -12, -25, -15, 500}, {-5, 25, 8, 25, 15, 460}};
  for (size_t i = 0; i < poses.size(); ++i) {
    views.push_back(testing::ProjectGrid(truth, poses[i], grid, 0.1, rng));
    const double* v = variant[i];
    views.push_back(
        testing::ProjectGrid(truth, testing::MakePose(v[0], v[1], v[2], {v[3], v[4], v[5]}, grid), grid, 0.1, rng));
  }
  const auto result = CrossValidate(views, CalibrationOptions{});
  ASSERT_TRUE(result.ok) << result.message;
  EXPECT_EQ(result.half_views[0].size(), 8u);
  EXPECT_EQ(result.half_views[1].size(), 8u);
  std::printf("halves of 8 views, 0.1 px noise: RMS %.4f px, max %.4f px\n", result.rms_px, result.max_px);
  // 0.1 px of corner noise over ~700 corners per half: each model is good to a few hundredths of a pixel.
  constexpr double kNoiseLevelPx = 0.05;  // measured 0.020 px on 2026-12-01
  EXPECT_LT(result.rms_px, kNoiseLevelPx);
  EXPECT_GE(result.max_px, result.rms_px);

  const auto too_few = CrossValidate({views.begin(), views.begin() + 5}, CalibrationOptions{});
  EXPECT_FALSE(too_few.ok);
  EXPECT_NE(too_few.message.find("at least 3 views; 5 view(s) give 3 and 2"), std::string::npos) << too_few.message;
}

}  // namespace
}  // namespace topocal::calib
