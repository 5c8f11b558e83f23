#include "calib/charuco_detector.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/aruco/charuco.hpp>

#include "calib/aruco_search.h"
#include "calib/corner_refinement.h"

namespace topocal::calib {
namespace {

// Window limits as for the other X-junctions (calib/kalibr_grid_detector.cc).
constexpr double kMinWindowSigmaPx = 1.0;
constexpr double kMaxWindowSigmaPx = 3.0;
constexpr double kMinEdgeWindowSigmaPx = 0.7;
// A corner needs this many detected neighbouring markers (OpenCV's local homography interpolation).
constexpr int kMinAdjacentMarkers = 2;

}  // namespace

CharucoDetections DetectCharuco(const cv::Mat& gray, const CharucoLayout& layout, const DetectionOptions& options) {
  CharucoDetections result;
  std::vector<int> ids, kept_ids;
  std::vector<std::vector<cv::Point2f>> quads, kept_quads;
  std::vector<cv::Point2f> corners;
  std::vector<int> corner_ids;
  try {
    const auto dictionary = cv::aruco::getPredefinedDictionary(*ArucoDictionaryId(layout.dictionary));
    const auto board = cv::aruco::CharucoBoard::create(layout.squares_x, layout.squares_y,
                                                       static_cast<float>(layout.square_size_mm),
                                                       static_cast<float>(layout.marker_size_mm), dictionary);
    SearchArucoMarkers(gray, dictionary, 1, &ids, &quads);
    for (size_t i = 0; i < ids.size(); ++i) {
      if (ids[i] >= layout.NumMarkers()) {
        ++result.markers_rejected;
        result.reasons.push_back(
            fmt::format("marker id {}: not on this board (ids 0..{})", ids[i], layout.NumMarkers() - 1));
        continue;
      }
      kept_ids.push_back(ids[i]);
      kept_quads.push_back(quads[i]);
    }
    result.markers_detected = static_cast<int>(kept_ids.size());
    if (!kept_ids.empty()) {
      cv::aruco::interpolateCornersCharuco(kept_quads, kept_ids, gray, board, corners, corner_ids, cv::noArray(),
                                           cv::noArray(), kMinAdjacentMarkers);
    }
  } catch (const cv::Exception& e) {
    result.message = fmt::format("OpenCV aruco failed: {}", e.err);
    return result;
  }
  // Pixels per mm from the markers' sides: the margin's size in the image sets the saddle window.
  std::vector<double> scale;
  for (const auto& q : kept_quads) {
    for (size_t k = 0; k < 4; ++k) scale.push_back(cv::norm(q[(k + 1) % 4] - q[k]) / layout.marker_size_mm);
  }
  double px_per_mm = 0;
  if (!scale.empty()) {
    std::nth_element(scale.begin(), scale.begin() + static_cast<std::ptrdiff_t>(scale.size() / 2), scale.end());
    px_per_mm = scale[scale.size() / 2];
  }
  cv::Mat image;
  if (options.refinement != CornerRefinement::kNone) gray.convertTo(image, CV_32F);
  for (size_t i = 0; i < corners.size(); ++i) {
    Eigen::Vector2d p(corners[i].x, corners[i].y);
    if (options.refinement != CornerRefinement::kNone) {
      SaddleFitOptions fit;
      fit.window_sigma_px = options.saddle_window_sigma_px > 0
                                ? options.saddle_window_sigma_px
                                : std::clamp(0.25 * layout.MarginMm() * px_per_mm, kMinWindowSigmaPx,
                                             kMaxWindowSigmaPx);
      const double room_px = std::min({p.x(), p.y(), gray.cols - 1.0 - p.x(), gray.rows - 1.0 - p.y()}) - 1.0;
      if (SaddleWindowHalfWidthPx(fit.window_sigma_px) > room_px) {
        fit.window_sigma_px = SaddleSigmaForRoomPx(room_px);
      }
      std::optional<Eigen::Vector2d> refined;
      if (fit.window_sigma_px >= kMinEdgeWindowSigmaPx) refined = RefineSaddle(image, p, fit);
      if (!refined) {
        result.reasons.push_back(fmt::format("corner {}: {}", corner_ids[i],
                                             fit.window_sigma_px < kMinEdgeWindowSigmaPx
                                                 ? "at the image edge, left out"
                                                 : "no saddle there (occluded or blurred), left out"));
        continue;
      }
      p = *refined;
    }
    result.corners.emplace_back(corner_ids[i], p);
  }
  std::sort(result.corners.begin(), result.corners.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  result.message = fmt::format("{}/{} corners from {} markers ({} rejected)", result.corners.size(),
                               layout.InnerCols() * layout.InnerRows(), result.markers_detected,
                               result.markers_rejected);
  return result;
}

}  // namespace topocal::calib
