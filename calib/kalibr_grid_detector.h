#pragma once
// AprilTag grids as Kalibr prints them (calib/target.h: tag36h11 inside a 2-cell black border, black squares in
// the gap crossings): two searches find the tags, topocal refines every tag corner as the X-junction it is.
//
// Two searches, one per tag id. OpenCV 4.6's contrib aruco has the tag36h11 codes (DICT_APRILTAG_36h11) and a
// `markerBorderBits` parameter; libapriltag 3.3 reads the same codes behind a 2-cell border once its family's layout
// is widened (calib/apriltag_raii.h: MakeKalibrTag36h11). Neither is enough alone: on gamma-encoded, JPEG-compressed
// views with tags of 20-42 px aruco finds 29 % of what libapriltag finds; on linear images, where a blurred tag
// corner sits exactly at mid-grey, libapriltag's threshold joins tags to their corner squares and finds ~10 % of the
// tags, aruco's 2x-upsampled search ~45 % (tests/calib/kalibr_grid_recall_test.cc; docs/calibration-targets.md).
// A tag found by both is kept once (aruco's corners); the same id at two places stays twice and is dropped as seen
// twice.
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
