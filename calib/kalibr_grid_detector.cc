#include "calib/kalibr_grid_detector.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/aruco.hpp>

#include "calib/aruco_search.h"
#include "calib/corner_refinement.h"

namespace topocal::calib {
namespace {

// Cells across Kalibr's black tag square: 6 data bits + 2 x 2 border cells.
constexpr double kKalibrTagCells = 10.0;
// Saddle window sigma limits (px). Below ~1 px the Gaussian weights see too few pixels for six coefficients; above
// 3 px the edges' bending by lens distortion across the window costs more than the noise it averages
// (calib/checkerboard_detector.cc measured the same trade-off).
constexpr double kMinWindowSigmaPx = 1.0;
constexpr double kMaxWindowSigmaPx = 3.0;
// Near the image edge a window down to this sigma is still tried before the corner is left out.
constexpr double kMinEdgeWindowSigmaPx = 0.7;
// How far inside the ink aruco's contour corners can be (2x-upsampled search at kAdaptiveThresholdConstant on the
// JPEG in data/: 1.8 px), and how far a refined corner may move from its start.
constexpr double kContourInsetPx = 2.0;
constexpr double kMaxCornerShiftPx = 4.0;

}  // namespace

AprilGridDetections DetectKalibrAprilGrid(const cv::Mat& gray, const AprilGridLayout& grid,
                                          const DetectionOptions& options) {
  AprilGridDetections result;
  std::vector<int> ids;
  std::vector<std::vector<cv::Point2f>> quads;
  try {
    // Kalibr's border: 2 cells (calib/target.h).
    SearchArucoMarkers(gray, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11), 2, &ids, &quads);
  } catch (const cv::Exception& e) {
    result.message = fmt::format("OpenCV aruco failed: {}", e.err);
    return result;
  }

  cv::Mat image;
  if (options.refinement != CornerRefinement::kNone) gray.convertTo(image, CV_32F);
  const double edge_limit_x = gray.cols - 1, edge_limit_y = gray.rows - 1;
  for (size_t i = 0; i < ids.size(); ++i) {
    const int index = ids[i] - grid.first_tag_id;
    if (index < 0 || index >= grid.NumTags()) {
      ++result.rejected;
      result.reasons.push_back(fmt::format("tag id {}: not on this grid (ids {}..{})", ids[i], grid.first_tag_id,
                                           grid.first_tag_id + grid.NumTags() - 1));
      continue;
    }
    TagDetection tag;
    tag.tag_index = index;
    for (size_t a = 0; a < 4; ++a) {
      tag.corners_px[static_cast<size_t>(kArucoToTopocal[a])] = Eigen::Vector2d(quads[i][a].x, quads[i][a].y);
    }
    if (options.refinement != CornerRefinement::kNone) {
      double side_px = 0;
      for (size_t k = 0; k < 4; ++k) side_px += 0.25 * (tag.corners_px[(k + 1) % 4] - tag.corners_px[k]).norm();
      const Eigen::Vector2d centre =
          0.25 * (tag.corners_px[0] + tag.corners_px[1] + tag.corners_px[2] + tag.corners_px[3]);
      const double symmetric_radius_px =
          std::min(2.0 * side_px / kKalibrTagCells, side_px * grid.tag_spacing_ratio);
      for (size_t k = 0; k < 4; ++k) {
        SaddleFitOptions fit;
        fit.window_sigma_px = options.saddle_window_sigma_px > 0
                                  ? options.saddle_window_sigma_px
                                  : std::clamp(0.25 * symmetric_radius_px, kMinWindowSigmaPx, kMaxWindowSigmaPx);
        // Near the image edge: the largest window that stays inside (one pixel spare for the corner's motion).
        const Eigen::Vector2d& p = tag.corners_px[k];
        const double room_px = std::min({p.x(), p.y(), edge_limit_x - p.x(), edge_limit_y - p.y()}) - 1.0;
        if (SaddleWindowHalfWidthPx(fit.window_sigma_px) > room_px) {
          fit.window_sigma_px = SaddleSigmaForRoomPx(room_px);
        }
        std::optional<Eigen::Vector2d> refined;
        if (fit.window_sigma_px >= kMinEdgeWindowSigmaPx) {
          // aruco's quad follows a thresholded contour, inside the tag's ink by up to ~2 px on blurred images; if the
          // fit does not converge from there, it starts again that far outwards along the tag's diagonal.
          fit.max_shift_px = kMaxCornerShiftPx;
          refined = RefineSaddle(image, p, fit);
          if (!refined) {
            const Eigen::Vector2d outwards = (p - centre).normalized();
            refined = RefineSaddle(image, p + kContourInsetPx * outwards, fit);
          }
        }
        if (refined) {
          tag.corners_px[k] = *refined;
        } else {
          tag.corner_found[k] = false;
          result.reasons.push_back(fmt::format(
              "tag id {} corner {}: {}", ids[i], k,
              fit.window_sigma_px < kMinEdgeWindowSigmaPx ? "at the image edge, left out"
                                                          : "no X-junction there (occluded, or no corner square?)"));
        }
      }
    } else {
      // aruco's contour corners lie on the outermost black pixels, half a pixel inside the ink's edge.
      const Eigen::Vector2d centre = 0.25 * (tag.corners_px[0] + tag.corners_px[1] + tag.corners_px[2] +
                                             tag.corners_px[3]);
      for (auto& c : tag.corners_px) c += 0.5 * (c - centre).cwiseSign();
    }
    if (std::none_of(tag.corner_found.begin(), tag.corner_found.end(), [](bool b) { return b; })) {
      ++result.rejected;
      continue;
    }
    result.tags.push_back(tag);
  }
  FinishAprilGridDetections(grid, &result);
  return result;
}

}  // namespace topocal::calib
