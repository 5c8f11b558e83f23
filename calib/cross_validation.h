#pragma once
// Cross-validation of a calibration (the check mrcal calls the most important one): the views are split into two
// interleaved halves (even and odd positions, so both span the whole capture), each half is calibrated on its own,
// and the two models are compared over the image.
//
// Difference of two models A and B at pixel q: the ray A sees at q (A.PixelToNormalized), carried into B's frame by
// the homography H of normalised coordinates that best maps A's rays onto B's over the whole grid (least squares,
// cv::findHomography), projected by B: d(q) = |B.Project(H a(q)) - q|. Removing H removes what two honest fits may
// legitimately disagree on -- a small rotation of the camera frame, a focal/principal-point trade against the
// poses -- and leaves what changes the correction: the distortion and the rest of the projection.
//
// Decision: the difference is reported where the views saw corners (grid cells holding a corner of any view, and
// their 8 neighbours). Beyond the data both models extrapolate (k3 especially) and differ by pixels whatever the
// quality of the corners (seeded test: 0.6-4 px RMS over a whole image whose corners no view covered).
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/calibrate.h"
#include "calib/observations.h"

namespace topocal::calib {

struct CrossValidationOptions {
  int grid_cols = 40;  // samples across the image
  int grid_rows = 30;
};

struct ModelDifferenceSample {
  Eigen::Vector2d pixel;
  double difference_px = 0;
};

struct CrossValidationResult {
  bool ok = false;
  std::string message;                     // why not, when !ok
  std::vector<int> half_views[2];          // indices into the caller's views
  CalibrationResult half[2];
  std::vector<ModelDifferenceSample> samples;  // the grid, where both models have an inverse
  double rms_px = 0;
  double max_px = 0;
};

// Differences of two calibrated cameras over a grid of their (common) image, homography removed; with `covered`
// non-empty, only at grid cells within one cell of one of these pixels.
std::vector<ModelDifferenceSample> ModelDifference(const model::CameraModel& a, const model::CameraModel& b,
                                                   const CrossValidationOptions& options = {},
                                                   const std::vector<Eigen::Vector2d>& covered = {});

// Needs 2 * options.min_views usable views. Never throws for content; !ok with a message otherwise.
CrossValidationResult CrossValidate(const std::vector<ViewObservations>& views, const CalibrationOptions& options,
                                    const CrossValidationOptions& cv_options = {});

// The two halves' difference over the image as an SVG map (plot/difference_map.h): where the models disagree.
std::string CrossValidationSvg(const CrossValidationResult& cv, int image_height_px);

}  // namespace topocal::calib
