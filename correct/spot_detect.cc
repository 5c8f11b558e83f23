#include "correct/spot_detect.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <ceres/ceres.h>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace topocal::correct {
namespace {

struct Stats {
  double median = 0, sigma = 0, bright = 0;
};

// Robust statistics from every 2nd pixel of every 2nd row (a quarter of the image: enough samples, a quarter of
// the cost). Integer images go through a histogram (one pass, no sort); float images through nth_element.
Stats RobustStats(const cv::Mat& img) {
  Stats s;
  if (img.depth() == CV_8U || img.depth() == CV_16U) {
    const int bins = img.depth() == CV_8U ? 256 : 65536;
    std::vector<uint32_t> hist(bins, 0);
    size_t n = 0;
    for (int r = 0; r < img.rows; r += 2) {
      if (img.depth() == CV_8U) {
        const auto* p = img.ptr<uint8_t>(r);
        for (int c = 0; c < img.cols; c += 2) ++hist[p[c]];
      } else {
        const auto* p = img.ptr<uint16_t>(r);
        for (int c = 0; c < img.cols; c += 2) ++hist[p[c]];
      }
      n += (img.cols + 1) / 2;
    }
    const auto quantile = [&](const std::vector<uint32_t>& h, double q) {
      const auto target = static_cast<size_t>(q * (n - 1));
      size_t acc = 0;
      for (int b = 0; b < static_cast<int>(h.size()); ++b) {
        acc += h[b];
        if (acc > target) return b;
      }
      return static_cast<int>(h.size()) - 1;
    };
    const int median = quantile(hist, 0.5);
    s.median = median;
    s.bright = quantile(hist, 0.9999);
    std::vector<uint32_t> dev(bins, 0);
    for (int b = 0; b < bins; ++b) dev[std::abs(b - median)] += hist[b];
    s.sigma = 1.4826 * quantile(dev, 0.5);
    return s;
  }
  std::vector<float> v;
  v.reserve(static_cast<size_t>(img.rows / 2 + 1) * (img.cols / 2 + 1));
  for (int r = 0; r < img.rows; r += 2) {
    const auto* p = img.ptr<float>(r);
    for (int c = 0; c < img.cols; c += 2) v.push_back(p[c]);
  }
  const auto pct = [&v](double q) {
    const auto k = static_cast<size_t>(std::clamp(q, 0.0, 1.0) * (v.size() - 1));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return static_cast<double>(v[k]);
  };
  s.bright = pct(0.9999);
  s.median = pct(0.5);
  for (auto& x : v) x = std::abs(x - static_cast<float>(s.median));
  s.sigma = 1.4826 * pct(0.5);
  return s;
}

// The bounding box of all above-threshold pixels, grown by `margin`: connected components run only there (the
// spot pattern covers ~6 % of a 12 Mpx frame). cv::boundingRect of a mask is one vectorised pass. Empty if nothing
// is above threshold.
cv::Rect ForegroundBox(const cv::Mat& mask, int margin) {
  const cv::Rect tight = cv::boundingRect(mask);
  if (tight.empty()) return {};
  const cv::Rect box(tight.x - margin, tight.y - margin, tight.width + 2 * margin, tight.height + 2 * margin);
  return box & cv::Rect(0, 0, mask.cols, mask.rows);
}

double At(const cv::Mat& img, int r, int c) {
  switch (img.depth()) {
    case CV_8U: return img.at<uint8_t>(r, c);
    case CV_16U: return img.at<uint16_t>(r, c);
    default: return img.at<float>(r, c);
  }
}

// Elliptical Gaussian with constant background; the inverse covariance parametrised by its Cholesky factor
// (l0, l1, l2 with L = [[l0, 0], [l1, l2]]) so it stays positive definite without bounds.
struct GaussianResidual {
  double u, v, value;
  template <typename T>
  bool operator()(const T* p, T* residual) const {
    // p: amplitude, cx, cy, l0, l1, l2, background
    const T dx = T(u) - p[1], dy = T(v) - p[2];
    const T a = p[3] * dx + p[4] * dy;  // L^T d
    const T b = p[5] * dy;
    residual[0] = p[0] * exp(T(-0.5) * (a * a + b * b)) + p[6] - T(value);
    return true;
  }
};

const cv::Mat& Disc(int radius) {
  static thread_local std::vector<cv::Mat> cache;
  if (static_cast<int>(cache.size()) <= radius) cache.resize(radius + 1);
  if (cache[radius].empty()) {
    cache[radius] = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
  }
  return cache[radius];
}

}  // namespace

bool SpotDetectionOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string m) {
    if (why) *why = std::move(m);
    return false;
  };
  if (!(threshold_sigmas > 0)) return fail("threshold_sigmas must be > 0");
  if (!(threshold_fraction >= 0 && threshold_fraction < 1)) return fail("threshold_fraction must be in [0, 1)");
  if (min_area_px < 1 || max_area_px < min_area_px) return fail("need 1 <= min_area_px <= max_area_px");
  if (window_margin_px < 0) return fail("window_margin_px must be >= 0");
  return true;
}

SpotDetection DetectSpots(const cv::Mat& image, const SpotDetectionOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("DetectSpots: " + why);
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F)) {
    throw std::invalid_argument("DetectSpots: the image must be one channel of 8-bit, 16-bit or float pixels");
  }
  SpotDetection out;
  if (image.empty()) return out;
  const Stats st = RobustStats(image);
  out.background_dn = st.median;
  out.noise_dn = st.sigma;
  out.threshold_dn = st.median + std::max(options.threshold_sigmas * st.sigma,
                                          options.threshold_fraction * (st.bright - st.median));
  cv::Mat full_mask;
  cv::compare(image, out.threshold_dn, full_mask, cv::CMP_GT);
  const cv::Rect box = ForegroundBox(full_mask, options.window_margin_px + 1);
  if (box.empty()) return out;
  // From here on everything is in the box's coordinates; centres are shifted back at the end.
  const cv::Mat image_box = image(box);
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(full_mask(box), labels, stats, centroids, 8, CV_32S);
  const double bg = out.background_dn;
  for (int k = 1; k < n; ++k) {
    const int area = stats.at<int>(k, cv::CC_STAT_AREA);
    if (area < options.min_area_px) {
      ++out.rejected_small;
      continue;
    }
    if (area > options.max_area_px) {
      ++out.rejected_large;
      continue;
    }
    const int m = options.window_margin_px;
    const int c0 = std::max(0, stats.at<int>(k, cv::CC_STAT_LEFT) - m);
    const int r0 = std::max(0, stats.at<int>(k, cv::CC_STAT_TOP) - m);
    const int c1 = std::min(image_box.cols - 1, stats.at<int>(k, cv::CC_STAT_LEFT) + stats.at<int>(k, cv::CC_STAT_WIDTH) - 1 + m);
    const int r1 = std::min(image_box.rows - 1, stats.at<int>(k, cv::CC_STAT_TOP) + stats.at<int>(k, cv::CC_STAT_HEIGHT) - 1 + m);
    // The window: the component grown by `m` pixels (a disc kernel), other components excluded. Following the
    // spot's own outline rather than its bounding box keeps the far window corners — pure noise with the largest
    // lever arm — out of the centroid.
    const cv::Rect roi(c0, r0, c1 - c0 + 1, r1 - r0 + 1);
    cv::Mat window = labels(roi) == k;
    if (m > 0) cv::dilate(window, window, Disc(m));
    double sw = 0, su = 0, sv = 0, peak = 0;
    for (int r = r0; r <= r1; ++r) {
      const int* lab = labels.ptr<int>(r);
      const uint8_t* win = window.ptr<uint8_t>(r - r0) - c0;
      for (int c = c0; c <= c1; ++c) {
        if (!win[c] || (lab[c] != 0 && lab[c] != k)) continue;
        const double w = At(image_box, r, c) - bg;
        sw += w;
        su += w * c;
        sv += w * r;
        peak = std::max(peak, w);
      }
    }
    if (!(sw > 0)) continue;
    DetectedSpot s;
    s.centre_px = {su / sw, sv / sw};
    s.flux_dn = sw;
    s.peak_dn = peak;
    s.area_px = area;
    if (options.method == CentroidMethod::kGaussianFit) {
      // Initial shape from the thresholded area: a Gaussian whose half-maximum disc has that area.
      const double sigma0 = std::max(0.7, std::sqrt(area / M_PI) / 1.1774);
      double p[7] = {peak, s.centre_px.x(), s.centre_px.y(), 1.0 / sigma0, 0.0, 1.0 / sigma0, 0.0};
      ceres::Problem problem;
      for (int r = r0; r <= r1; ++r) {
        const int* lab = labels.ptr<int>(r);
        const uint8_t* win = window.ptr<uint8_t>(r - r0) - c0;
        for (int c = c0; c <= c1; ++c) {
          if (!win[c] || (lab[c] != 0 && lab[c] != k)) continue;
          problem.AddResidualBlock(new ceres::AutoDiffCostFunction<GaussianResidual, 1, 7>(
                                       new GaussianResidual{double(c), double(r), At(image_box, r, c) - bg}),
                                   nullptr, p);
        }
      }
      ceres::Solver::Options so;
      so.linear_solver_type = ceres::DENSE_QR;
      so.max_num_iterations = 50;
      so.function_tolerance = 1e-12;
      so.parameter_tolerance = 1e-12;
      ceres::Solver::Summary summary;
      ceres::Solve(so, &problem, &summary);
      const Eigen::Vector2d fit(p[1], p[2]);
      s.fit_converged = summary.termination_type == ceres::CONVERGENCE && std::isfinite(p[1]) && std::isfinite(p[2]) &&
                        (fit - s.centre_px).norm() < 2.0;  // a fit that wanders off the blob is not a centre
      if (s.fit_converged) s.centre_px = fit;
    }
    s.centre_px += Eigen::Vector2d(box.x, box.y);
    out.spots.push_back(s);
  }
  return out;
}

}  // namespace topocal::correct
