#pragma once
// Internal to correct/ (spot_detect.cc, spot_deblend.cc, spot_fit.cc): a segmented component and the window its
// centre is estimated in, the deblending of merged and close spots, and the two model fits that refine a centroid
// (docs/spot-noise.md). Not part of the library's interface.
#include <vector>

#include <opencv2/core.hpp>

#include "correct/spot_detect.h"

namespace topocal::correct::detail {

inline double At(const cv::Mat& img, int r, int c) {
  switch (img.depth()) {
    case CV_8U: return img.at<uint8_t>(r, c);
    case CV_16U: return img.at<uint16_t>(r, c);
    default: return img.at<float>(r, c);
  }
}

inline bool Saturates(const cv::Mat& img, double value) {
  return (img.depth() == CV_8U && value >= 255.0) || (img.depth() == CV_16U && value >= 65535.0);
}

// One component: what segmentation found, and the window its centre is estimated in.
struct Component {
  int label = 0;
  cv::Rect roi;      // window bounding box, box coordinates
  cv::Mat window;    // CV_8U mask over roi: the component grown by the margin
  DetectedSpot spot; // centroid, flux, peak, area, flags (box coordinates)
  std::vector<double> values;  // the component's own pixels above background (for the profile test)
  std::vector<int> neighbours; // labels of the other components within near_blob_gap_px of the window
};

// Splits the components of `labels` (box coordinates; `stats` as cv::connectedComponentsWithStats gives them) that
// hold several spots merged above the threshold; the new components are appended (spot_deblend.cc).
void DeblendMerged(const cv::Mat& image_box, double threshold_dn, double noise_dn, const SpotDetectionOptions& options,
                   cv::Mat* labels, cv::Mat* stats);

// Cuts comp's window down to the pixels nearer to its own component than to any other (spot_deblend.cc).
void KeepNearestPixels(const cv::Mat& labels, int margin, Component* comp);

// kGaussianFit: each component's centroid replaced by an elliptical 2-D Gaussian's centre fitted to its window
// (unweighted; kept for comparison). A fit that fails or wanders > 2 px off keeps the centroid (fit_converged false).
void RefineByGaussianFit(const cv::Mat& image_box, const cv::Mat& labels, double bg, std::vector<Component>* comps);

// The gain is measured only from at least this many spots: one spot's estimate carries its own misfit.
inline constexpr int kMinGainEvidenceSpots = 10;

struct NoiseModelFit {
  double gain_e_per_dn = 0;  // the gain used: given, measured, or 0 (read noise only)
  bool gain_measured = false;
  int evidence_spots = 0;    // spots whose residuals or plateau gave evidence on the gain
};

// kWeightedPsfFit: the pixel-integrated PSF fit of every PSF-like component (flat-topped ones keep their centroid),
// weighted by the noise model read_var + signal / gain. gain_e_per_dn 0: measured from the first pass' residuals
// and the flat-topped spots' plateaus (docs/spot-noise.md), when kMinGainEvidenceSpots spots give evidence.
NoiseModelFit RefineByPsfFit(const cv::Mat& image_box, const cv::Mat& labels, double bg, double threshold_dn, double read_var,
                      double gain_e_per_dn, std::vector<Component>* comps);

}  // namespace topocal::correct::detail
