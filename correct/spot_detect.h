#pragma once
// Spot detection in a raw sensor image: segmentation and sub-pixel centres.
//
//  1. Background and noise from a robust histogram of a subsample (median; 1.4826 * MAD).
//  2. Global threshold  bg + max(threshold_sigmas * noise, threshold_fraction * (bright - bg)),  `bright` the
//     99.99th percentile of the subsample (the spots' level); the second term keeps the threshold clear of the
//     blur tails between neighbouring spots in low-noise images.
//     The threshold's noise is the smaller of the histogram's MAD and the MAD of neighbouring-pixel differences
//     (a skin over part of the frame widens the first). Where the histogram is wider than the pixel noise and the
//     local background (the image's floor over 24 px windows) rises above the global one by more than 4 noise
//     sigmas — a lid's skin, its margin, a bright iris — a pixel must also clear that local background by the same
//     margin (local_background). noise_dn stays the histogram's MAD; the read noise is measured apart
//     (SpotDetection::read_noise_dn).
//  3. Connected components (cv::connectedComponentsWithStats, 8-connected); components outside
//     [min_area_px, max_area_px] are dropped and counted.
//  4. Sub-pixel centre per component in a window = its bounding box grown by window_margin_px, ignoring the
//     pixels of other components:
//     * kIntensityWeighted: centroid of (I - bg), no clipping (clipping negative noise would bias towards the
//       window centre);
//     * kGaussianFit: elliptical 2-D Gaussian + constant background fitted by Ceres to the same pixels, started at
//       the centroid (unweighted, saturated pixels kept: kept for comparison).
//     * kWeightedPsfFit (default): a pixel-integrated isotropic Gaussian PSF (flux, centre, width) + local background,
//       fitted to the same pixels by weighted least squares with the noise model of docs/spot-noise.md
//       (Poisson + read noise: var_i = read_noise^2 + signal_i / gain), saturated pixels left out. Two solves: the
//       first with read-noise weights gives the model signal from which the gain is estimated (unless given) and
//       the weights of the second are computed. This is the maximum-likelihood centre of a Gaussian-approximated
//       Poisson + read noise image; it reaches the Cramer-Rao bound (tests/correct/spot_crb_test.cc). Spots whose
//       profile is flat-topped rather than PSF-like (the image of a screen disc several PSF widths across: more of
//       the thresholded pixels above half the peak than a Gaussian has) keep their centroid, which is the better
//       estimator there (docs/spot-noise.md has the measurements).
//     Close neighbours share the gap between them: where another component lies within near_blob_gap_px of the
//     window, the window keeps only the pixels nearer to its own component (each spot's light less its tail across
//     the line of equal distance, plus the neighbour's tail across it: mirror images for like spots). A sensor
//     whose spots are 10 px apart (3 MP) measures every spot (docs/spot-noise.md, "Close neighbours").
//  5. Flags per spot (SpotFlag): kNearBlob when such a neighbour is not a like spot — a blob left out as too large,
//     or one whose light above background differs from the spot's by more than 2x (a glint, a spot cut by a lash) —
//     so that its tail can pull the centre; kSaturated when a pixel of the window is at full scale, kTruncated when
//     the window is cut by the image border.
//  The centres are OpenCV pixel coordinates (centre of the top-left pixel = (0, 0)).
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include "util/io.h"

namespace topocal::correct {

enum class CentroidMethod { kIntensityWeighted, kGaussianFit, kWeightedPsfFit };
// The names the command line uses: "centroid", "gaussian", "psf" (default). Throws util::InputError.
CentroidMethod CentroidMethodFromName(const std::string& name);
const char* CentroidMethodName(CentroidMethod method) noexcept;

enum SpotFlag : unsigned {
  kNearBlob = 1u,   // an unlike blob's light reaches the spot's window (glint, lid margin): centre may be pulled
  kSaturated = 2u,  // a window pixel at full scale (left out by kWeightedPsfFit)
  kTruncated = 4u,  // the window is cut by the image border: centre biased towards the inside
  kFluxOutlier = 8u,  // its light differs from its ring neighbours' (a lash's shadow, the lid margin, a dry patch of
                      // tear film, a merged glint): part of the spot is lost or added, the centre pulled
                      // (set by DetectAndIndexSpots, which knows the neighbours)
  kUnevenBackground = 16u,  // the background about the spot is not a plane (a lid margin, a lash's edge): the
                            // centre may be pulled
  // Set by the surface's check of the identities (pipeline/surface_labelling.h), which knows the surface the other
  // spots give:
  kSurfaceOutlier = 32u,   // its slope stands out of its neighbours' on that surface: a pulled centre or a wrong
                           // identity; left out of the measurement
  kSurfaceLabelled = 64u,  // identified by that surface's prediction (the pattern's lattice left it free)
};
// "near_blob|saturated|truncated|flux_outlier|uneven_background|surface_outlier|surface_labelled" (empty for 0).
std::string SpotFlagsText(unsigned flags);

struct SpotDetectionOptions {
  CentroidMethod method = CentroidMethod::kWeightedPsfFit;
  // Noise model of kWeightedPsfFit (docs/spot-noise.md). gain_e_per_dn 0: measured from the image (the spots' fit
  // residuals against their expectation, the flat-topped spots' plateaus); read_noise_dn 0: measured from the
  // background (maximum likelihood of its histogram's core as rounded Gaussian samples).
  double gain_e_per_dn = 0;
  double read_noise_dn = 0;
  // Another blob's pixels within near_blob_gap_px of this spot's window (the spot grown by window_margin_px): the
  // two share the gap between them, and kNearBlob is set if the blob is not a like spot (step 5).
  int near_blob_gap_px = 1;
  double threshold_sigmas = 8.0;
  bool local_background = true;  // step 2's local background (skin, lid margin, iris)
  double threshold_fraction = 0.25;
  int min_area_px = 3;
  int max_area_px = 5000;
  int window_margin_px = 3;
  bool IsValid(std::string* why) const;
};

struct DetectedSpot {
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  double flux_dn = 0;        // sum of background-subtracted intensity in the window
  double peak_dn = 0;        // brightest pixel above background
  int area_px = 0;           // pixels above threshold
  bool fit_converged = true; // fits only; false: the centroid is kept
  unsigned flags = 0;        // SpotFlag bits
};

struct SpotDetection {
  std::vector<DetectedSpot> spots;
  double background_dn = 0, noise_dn = 0, threshold_dn = 0;
  int rejected_small = 0, rejected_large = 0;
  // The noise model (docs/spot-noise.md): the read noise (DN, quantisation excluded; given or measured for every
  // method) and, for kWeightedPsfFit, the gain (e-/DN; given, measured from gain_evidence_spots spots, or 0 when
  // fewer than 10 gave evidence: the fit's weights are then the read noise's alone).
  double read_noise_dn = 0, gain_e_per_dn = 0;
  bool gain_measured = false;
  int gain_evidence_spots = 0;
  std::string gain_source;        // one phrase: "given", "measured from N spots", or why it was not measured
  std::string read_noise_source;  // one phrase: given, or which statistic of the background measured it
};

// `image`: CV_8UC1, CV_16UC1 or CV_32FC1. Throws util::InputError for other types or invalid options.
SpotDetection DetectSpots(const cv::Mat& image, const SpotDetectionOptions& options = {});

}  // namespace topocal::correct
