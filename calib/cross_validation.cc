#include "calib/cross_validation.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <opencv2/calib3d.hpp>

#include "plot/difference_map.h"

namespace topocal::calib {

std::vector<ModelDifferenceSample> ModelDifference(const model::CameraModel& a, const model::CameraModel& b,
                                                   const CrossValidationOptions& options,
                                                   const std::vector<Eigen::Vector2d>& covered) {
  const double cell_w = static_cast<double>(a.width_px) / options.grid_cols;
  const double cell_h = static_cast<double>(a.height_px) / options.grid_rows;
  std::vector<uint8_t> near_data(static_cast<size_t>(options.grid_cols * options.grid_rows), covered.empty() ? 1 : 0);
  for (const auto& p : covered) {
    const int ci = static_cast<int>(std::floor((p.x() + 0.5) / cell_w));
    const int cj = static_cast<int>(std::floor((p.y() + 0.5) / cell_h));
    for (int j = cj - 1; j <= cj + 1; ++j) {
      for (int i = ci - 1; i <= ci + 1; ++i) {
        if (i >= 0 && j >= 0 && i < options.grid_cols && j < options.grid_rows) {
          near_data[static_cast<size_t>(j * options.grid_cols + i)] = 1;
        }
      }
    }
  }
  std::vector<Eigen::Vector2d> pixels;
  std::vector<cv::Point2d> rays_a, rays_b;
  for (int j = 0; j < options.grid_rows; ++j) {
    for (int i = 0; i < options.grid_cols; ++i) {
      if (!near_data[static_cast<size_t>(j * options.grid_cols + i)]) continue;
      // Sample centres of a grid over the whole image (OpenCV pixel convention: the image spans -0.5 .. width-0.5).
      const Eigen::Vector2d q(-0.5 + (i + 0.5) * a.width_px / options.grid_cols,
                              -0.5 + (j + 0.5) * a.height_px / options.grid_rows);
      const auto ra = a.PixelToNormalized(q), rb = b.PixelToNormalized(q);
      if (!ra || !rb) continue;  // beyond a model's fold: no ray to compare
      pixels.push_back(q);
      rays_a.emplace_back(ra->x(), ra->y());
      rays_b.emplace_back(rb->x(), rb->y());
    }
  }
  std::vector<ModelDifferenceSample> samples;
  if (pixels.size() < 4) return samples;
  const cv::Mat h = cv::findHomography(rays_a, rays_b, 0);
  if (h.empty()) return samples;
  Eigen::Matrix3d hm;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) hm(r, c) = h.at<double>(r, c);
  }
  for (size_t k = 0; k < pixels.size(); ++k) {
    const Eigen::Vector3d mapped = hm * Eigen::Vector3d(rays_a[k].x, rays_a[k].y, 1.0);
    const Eigen::Vector2d projected = b.Project(mapped / mapped.z());
    samples.push_back({pixels[k], (projected - pixels[k]).norm()});
  }
  return samples;
}

CrossValidationResult CrossValidate(const std::vector<ViewObservations>& views, const CalibrationOptions& options,
                                    const CrossValidationOptions& cv_options) {
  CrossValidationResult result;
  std::vector<ViewObservations> halves[2];
  for (size_t i = 0; i < views.size(); ++i) {
    halves[i % 2].push_back(views[i]);
    result.half_views[i % 2].push_back(static_cast<int>(i));
  }
  if (static_cast<int>(halves[1].size()) < options.min_views) {
    result.message = fmt::format("cross-validation needs two halves of at least {} views; {} view(s) give {} and {}",
                                 options.min_views, views.size(), halves[0].size(), halves[1].size());
    return result;
  }
  for (int h = 0; h < 2; ++h) {
    result.half[h] = CalibrateMultiView(halves[h], options);
    if (!result.half[h].ok()) {
      result.message = fmt::format("cross-validation: half {} ({} views) did not calibrate: {}", h + 1,
                                   halves[h].size(), result.half[h].message);
      return result;
    }
  }
  std::vector<Eigen::Vector2d> covered;
  for (const auto& v : views) {
    for (const auto& c : v.corners) covered.push_back(c.image_px);
  }
  result.samples = ModelDifference(result.half[0].camera, result.half[1].camera, cv_options, covered);
  if (result.samples.empty()) {
    result.message = "cross-validation: the two models share no invertible part of the image";
    return result;
  }
  double sum2 = 0;
  for (const auto& s : result.samples) {
    sum2 += s.difference_px * s.difference_px;
    result.max_px = std::max(result.max_px, s.difference_px);
  }
  result.rms_px = std::sqrt(sum2 / static_cast<double>(result.samples.size()));
  result.ok = true;
  return result;
}

std::string CrossValidationSvg(const CrossValidationResult& cv, int image_height_px) {
  plot::DifferenceMap map;
  map.title = fmt::format("Cross-validation: two halves of the views ({} and {}), homography removed",
                          cv.half_views[0].size(), cv.half_views[1].size());
  map.note = fmt::format("difference of the two models: RMS {:.4f} px, max {:.4f} px over {} samples", cv.rms_px,
                         cv.max_px, cv.samples.size());
  map.image_height_px = image_height_px;
  for (const auto& s : cv.samples) map.samples.push_back({s.pixel.x(), s.pixel.y(), s.difference_px});
  return plot::RenderDifferenceMapSvg(map);
}

}  // namespace topocal::calib
