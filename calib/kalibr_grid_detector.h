#pragma once
// AprilTag grids as Kalibr prints them (calib/target.h: tag36h11 inside a 2-cell black border, black squares in
// the gap crossings): OpenCV's contrib aruco finds the tags, topocal refines every tag corner as the X-junction it is.
//
// Why aruco. libapriltag 3.3 (Debian) decodes only its own 1-cell-border layout: 0 tags on both real Kalibr photos in
// data/. OpenCV 4.6's aruco has the same tag36h11 codes (DICT_APRILTAG_36h11) and a `markerBorderBits` parameter:
// with 2 it finds 66/66 and 36/36 tags on them (docs/calibration-targets.md), so no tag family is written by hand.
//
// Corner numbering. aruco's corners 0..3 of a tag are, for libapriltag's upright tag (the way Kalibr prints it),
// bottom-right, bottom-left, top-left, top-right; topocal's k (calib/target.h) is libapriltag's p[k]:
// k = kArucoToTopocal[aruco index].
//
// Refinement. Kalibr's corner squares make every tag corner an X-junction: the tag's black border and the black
// square sit in opposite quadrants, the two white gaps in the other two. That is the checkerboard's point symmetry,
// so the saddle fit of calib/corner_refinement.h is unbiased there, as long as its window stays where the symmetry
// holds: within the 2-cell border of the tag and within the gap (radius R = min(2 cells, gap)). Window sigma R / 4
// (weights at R below exp(-8)), clamped to [kMinWindowSigmaPx, kMaxWindowSigmaPx]. A corner whose window leaves
// the image is retried with the largest window that fits; one that still cannot be refined is left out with its
// reason, the tag's other corners are kept.
#include <array>

#include <opencv2/core/mat.hpp>

#include "calib/apriltag_detector.h"
#include "calib/detect.h"
#include "calib/target.h"

namespace topocal::calib {

inline constexpr std::array<int, 4> kArucoToTopocal = {1, 0, 3, 2};

// `gray` is CV_8UC1; `grid` must have border_bits == 2. Never throws for image content.
AprilGridDetections DetectKalibrAprilGrid(const cv::Mat& gray, const AprilGridLayout& grid,
                                          const DetectionOptions& options);

}  // namespace topocal::calib
