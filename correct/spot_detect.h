#pragma once
// Spot detection in a raw sensor image: segmentation and sub-pixel centres.
//
//  1. Background and noise from a robust histogram of a subsample (median; 1.4826 * MAD).
//  2. Global threshold  bg + max(threshold_sigmas * noise, threshold_fraction * (bright - bg)),  `bright` the
//     99.99th percentile of the subsample (the spots' level); the second term keeps the threshold clear of the
//     blur tails between neighbouring spots in low-noise images.
//  3. Connected components (cv::connectedComponentsWithStats, 8-connected); components outside
//     [min_area_px, max_area_px] are dropped and counted.
//  4. Sub-pixel centre per component in a window = its bounding box grown by window_margin_px, ignoring the
//     pixels of other components:
//     * kIntensityWeighted: centroid of (I - bg), no clipping (clipping negative noise would bias towards the
//       window centre);
//     * kGaussianFit: elliptical 2-D Gaussian + constant background fitted by Ceres to the same pixels, started at
//       the centroid.
//  The centres are OpenCV pixel coordinates (centre of the top-left pixel = (0, 0)).
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace topocal::correct {

enum class CentroidMethod { kIntensityWeighted, kGaussianFit };

struct SpotDetectionOptions {
  CentroidMethod method = CentroidMethod::kIntensityWeighted;
  double threshold_sigmas = 8.0;
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
  bool fit_converged = true; // kGaussianFit only; false: the centroid is kept
};

struct SpotDetection {
  std::vector<DetectedSpot> spots;
  double background_dn = 0, noise_dn = 0, threshold_dn = 0;
  int rejected_small = 0, rejected_large = 0;
};

// `image`: CV_8UC1, CV_16UC1 or CV_32FC1. Throws std::invalid_argument for other types or invalid options.
SpotDetection DetectSpots(const cv::Mat& image, const SpotDetectionOptions& options = {});

}  // namespace topocal::correct
