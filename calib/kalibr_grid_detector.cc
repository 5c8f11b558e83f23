#include "calib/kalibr_grid_detector.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/aruco.hpp>

#include "calib/apriltag_raii.h"
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

// libapriltag's error correction for the Kalibr family: 2 bits, the library's own default. tag36h11's codes are 11
// bits apart, so a code corrected by 2 is still 9 bits from any other. With 1 bit the detector keeps 1173 instead of
// 1209 tags on the recall test's compressed views (tests/calib/kalibr_grid_recall_test.cc), 98.7 % instead of
// 101.7 % of libapriltag's, lost on the hardest (blur 1.4 px, 25 px tags, JPEG 30).
constexpr int kLibapriltagCorrectedBits = 2;

// libapriltag's decoding table for 2 corrected bits is ~36 MB and takes ~150 ms to build, longer than a detection:
// each thread builds it once, with its own detector (libapriltag keeps per-detection state in both).
struct KalibrLibapriltag {
  apriltag_raii::Tag36h11Family family;  // declared first: the detector, destroyed first, releases its table
  apriltag_raii::Detector detector;
};

apriltag_detector_t* ThreadKalibrDetector() {
  thread_local const KalibrLibapriltag instance = [] {
    KalibrLibapriltag made{apriltag_raii::MakeKalibrTag36h11(), apriltag_raii::Detector(apriltag_detector_create())};
    if (made.family && made.detector) {
      apriltag_detector_add_family_bits(made.detector.get(), made.family.get(), kLibapriltagCorrectedBits);
      made.detector->refine_edges = true;
      made.detector->nthreads = 1;
    }
    return made;
  }();
  return instance.family && instance.detector ? instance.detector.get() : nullptr;
}

// A tag one of the two searches decoded: its id and corners (calib/target.h's k, OpenCV convention, unrefined).
struct TagCandidate {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners_px;
  bool on_contour = false;  // aruco's: corners on the outermost black pixels, half a pixel inside the ink's edge
  Eigen::Vector2d Centre() const { return 0.25 * (corners_px[0] + corners_px[1] + corners_px[2] + corners_px[3]); }
  double SidePx() const {
    double side = 0;
    for (size_t k = 0; k < 4; ++k) side += 0.25 * (corners_px[(k + 1) % 4] - corners_px[k]).norm();
    return side;
  }
};

// OpenCV's aruco with Kalibr's 2-cell border (calib/aruco_search.h). Throws cv::Exception.
std::vector<TagCandidate> ArucoCandidates(const cv::Mat& gray) {
  std::vector<int> ids;
  std::vector<std::vector<cv::Point2f>> quads;
  SearchArucoMarkers(gray, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11), 2, &ids, &quads);
  std::vector<TagCandidate> candidates(ids.size());
  for (size_t i = 0; i < ids.size(); ++i) {
    candidates[i].id = ids[i];
    candidates[i].on_contour = true;
    for (size_t a = 0; a < 4; ++a) {
      candidates[i].corners_px[static_cast<size_t>(kArucoToTopocal[a])] = Eigen::Vector2d(quads[i][a].x, quads[i][a].y);
    }
  }
  return candidates;
}

// libapriltag with tag36h11's codes behind Kalibr's border (apriltag_raii.h), at full resolution (unless the caller
// decimates) with its edge refinement. It reads JPEG-blurred small tags that aruco's thresholded contours lose.
std::vector<TagCandidate> LibapriltagCandidates(const cv::Mat& gray, const DetectionOptions& options,
                                                std::string* failure) {
  apriltag_detector_t* detector = ThreadKalibrDetector();
  if (!detector) {
    *failure = "libapriltag: cannot create the detector";
    return {};
  }
  detector->quad_decimate = static_cast<float>(options.quad_decimate);
  // libapriltag reads but does not write the pixels; it takes a non-const buffer, so hand it a private copy.
  cv::Mat copy = gray.clone();
  image_u8_t image{copy.cols, copy.rows, static_cast<int32_t>(copy.step[0]), copy.data};
  const apriltag_raii::Detections detections(apriltag_detector_detect(detector, &image));
  if (!detections) {
    *failure = "libapriltag: detection failed";
    return {};
  }
  std::vector<TagCandidate> candidates;
  for (int i = 0; i < zarray_size(detections.get()); ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(detections.get(), i, &det);
    TagCandidate candidate;
    candidate.id = det->id;
    // libapriltag's p[k] is calib/target.h's corner k (calib/apriltag_detector.h), half a pixel off OpenCV's.
    for (size_t k = 0; k < 4; ++k) {
      candidate.corners_px[k] = Eigen::Vector2d(det->p[k][0], det->p[k][1]) +
                                Eigen::Vector2d::Constant(kAprilTagToOpenCvOffsetPx);
    }
    candidates.push_back(candidate);
  }
  return candidates;
}

// Both searches' tags, one per tag where they agree. A tag libapriltag finds under an id aruco put elsewhere stays
// twice, so that FinishAprilGridDetections drops both rather than guess which decode was wrong.
std::vector<TagCandidate> MergeCandidates(std::vector<TagCandidate> aruco, const std::vector<TagCandidate>& april) {
  const size_t from_aruco = aruco.size();
  for (const TagCandidate& candidate : april) {
    bool same_tag = false;
    for (size_t i = 0; i < from_aruco && !same_tag; ++i) {
      same_tag = aruco[i].id == candidate.id &&
                 (aruco[i].Centre() - candidate.Centre()).norm() < 0.25 * candidate.SidePx();
    }
    if (!same_tag) aruco.push_back(candidate);
  }
  return aruco;
}

// Refines every corner of `tag` as an X-junction; a corner that cannot be refined is marked not found, its reason
// added.
void RefineTagCorners(const cv::Mat& image, const AprilGridLayout& grid, const DetectionOptions& options, int id,
                      TagDetection* tag, std::vector<std::string>* reasons) {
  const double side_px = TagCandidate{id, tag->corners_px, false}.SidePx();
  const Eigen::Vector2d centre = TagCandidate{id, tag->corners_px, false}.Centre();
  const double symmetric_radius_px = std::min(2.0 * side_px / kKalibrTagCells, side_px * grid.tag_spacing_ratio);
  const double edge_limit_x = image.cols - 1, edge_limit_y = image.rows - 1;
  for (size_t k = 0; k < 4; ++k) {
    SaddleFitOptions fit;
    fit.window_sigma_px = options.saddle_window_sigma_px > 0
                              ? options.saddle_window_sigma_px
                              : std::clamp(0.25 * symmetric_radius_px, kMinWindowSigmaPx, kMaxWindowSigmaPx);
    // Near the image edge: the largest window that stays inside (one pixel spare for the corner's motion).
    const Eigen::Vector2d& p = tag->corners_px[k];
    const double room_px = std::min({p.x(), p.y(), edge_limit_x - p.x(), edge_limit_y - p.y()}) - 1.0;
    if (SaddleWindowHalfWidthPx(fit.window_sigma_px) > room_px) fit.window_sigma_px = SaddleSigmaForRoomPx(room_px);
    std::optional<Eigen::Vector2d> refined;
    if (fit.window_sigma_px >= kMinEdgeWindowSigmaPx) {
      // aruco's quad follows a thresholded contour, inside the tag's ink by up to ~2 px on blurred images; if the
      // fit does not converge from there, it starts again that far outwards along the tag's diagonal.
      fit.max_shift_px = kMaxCornerShiftPx;
      refined = RefineSaddle(image, p, fit);
      if (!refined) refined = RefineSaddle(image, p + kContourInsetPx * (p - centre).normalized(), fit);
    }
    if (refined) {
      tag->corners_px[k] = *refined;
    } else {
      tag->corner_found[k] = false;
      reasons->push_back(fmt::format("tag id {} corner {}: {}", id, k,
                                     fit.window_sigma_px < kMinEdgeWindowSigmaPx
                                         ? "at the image edge, left out"
                                         : "no X-junction there (occluded, or no corner square?)"));
    }
  }
}

}  // namespace

AprilGridDetections DetectKalibrAprilGrid(const cv::Mat& gray, const AprilGridLayout& grid,
                                          const DetectionOptions& options) {
  AprilGridDetections result;
  std::vector<TagCandidate> aruco;
  try {
    aruco = ArucoCandidates(gray);
  } catch (const cv::Exception& e) {
    result.message = fmt::format("OpenCV aruco failed: {}", e.err);
    return result;
  }
  std::string failure;
  const auto candidates = MergeCandidates(std::move(aruco), LibapriltagCandidates(gray, options, &failure));
  if (!failure.empty()) result.reasons.push_back(failure);

  cv::Mat image;
  if (options.refinement != CornerRefinement::kNone) gray.convertTo(image, CV_32F);
  for (const TagCandidate& candidate : candidates) {
    const int index = candidate.id - grid.first_tag_id;
    if (index < 0 || index >= grid.NumTags()) {
      ++result.rejected;
      result.reasons.push_back(fmt::format("tag id {}: not on this grid (ids {}..{})", candidate.id,
                                           grid.first_tag_id, grid.first_tag_id + grid.NumTags() - 1));
      continue;
    }
    TagDetection tag;
    tag.tag_index = index;
    tag.corners_px = candidate.corners_px;
    if (options.refinement != CornerRefinement::kNone) {
      RefineTagCorners(image, grid, options, candidate.id, &tag, &result.reasons);
    } else {
      const Eigen::Vector2d centre = candidate.Centre();
      if (candidate.on_contour) {
        for (auto& c : tag.corners_px) c += 0.5 * (c - centre).cwiseSign();
      }
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
