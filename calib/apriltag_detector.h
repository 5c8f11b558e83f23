#pragma once
// AprilTag grid corners: libapriltag 3 finds tag36h11 tags, topocal filters them and refines their corners.
//
// Pixel convention. libapriltag samples pixel (x, y) at (x + 0.5, y + 0.5): its corner coordinates are those of
// OpenCV plus half a pixel, so OpenCV = libapriltag - 0.5 on both axes (kAprilTagToOpenCvOffsetPx; established by
// apriltag_test.cc on renders with exact truth, where the opposite sign leaves a 1 px error).
//
// Corner numbering. libapriltag's det->p[0..3] of an upright tag (y down) are bottom-left, bottom-right,
// top-right, top-left — the numbering calib/target.h uses, so corner k of the target is det->p[k].
//
// Refinement. Each of the tag's four sides is fitted (Ceres) with a blurred-step model over a strip of pixels
// along it, excluding the corner regions:
//     I(t, n) = black + (white - black) * (1 + erf((n - rho(t)) / (sqrt(2) s))) / 2,
//     rho(t) = rho0 + rho1 t + rho2 t^2   (t in [-1, 1] along the side; rho2 follows lens-distortion bending)
// where n is the signed distance from the detector's side line (outwards). A symmetric blur puts the model's
// half-level exactly on the ink edge, whatever its width. Corner k is the intersection of the two fitted side
// curves that meet there.
#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "calib/detect.h"
#include "calib/target.h"

namespace topocal::calib {

inline constexpr double kAprilTagToOpenCvOffsetPx = -0.5;

struct TagDetection {
  int tag_index = 0;                          // tag id - firstTagId
  std::array<Eigen::Vector2d, 4> corners_px;  // corner k as in calib/target.h, OpenCV convention
  std::array<bool, 4> corner_found{true, true, true, true};  // false: corner k could not be refined (left out)
  double decision_margin = 0;
  int hamming = 0;
};

struct AprilGridDetections {
  std::vector<TagDetection> tags;  // ascending tag_index, refined (unless options.refinement == kNone)
  int rejected = 0;                // dropped by hamming / margin / id / failed refinement
  std::vector<std::string> reasons;  // one line per rejected tag or left-out corner ("tag 7: id not on the grid")
  std::string message;
};

// `gray` is CV_8UC1. Never throws for image content.
AprilGridDetections DetectAprilGrid(const cv::Mat& gray, const AprilGridLayout& grid, const DetectionOptions& options);

// The last step of both AprilGrid detectors (libapriltag's and the Kalibr-print one): tags sorted by index, a tag
// id seen twice dropped (both: a misdetection of one of them, which is not guessed) with its reason, a tag whose
// corners are not where its neighbours put its id (a misread id) dropped with its reason, the summary.
void FinishAprilGridDetections(const AprilGridLayout& grid, AprilGridDetections* detections);

}  // namespace topocal::calib
