#include "correct/background_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <vector>

#include <ceres/autodiff_first_order_function.h>
#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>

namespace topocal::correct::detail {
namespace {

constexpr double kMadToSigma = 1.4826;

// Quantiles of integer samples held as a histogram, each count spread uniformly over its rounding interval
// [b - 1/2, b + 1/2] (the samples are a continuous quantity rounded by the ADC). The integer quantile moves in whole
// DN: at a read noise of a few DN the MAD of an 8-bit image is 3 where the noise gives 2.53, and 1.4826 MAD reads
// 4.46 DN for 3.75. Written here because neither OpenCV nor the standard library interpolates a histogram's
// quantiles.
class SpreadHistogram {
 public:
  explicit SpreadHistogram(const std::vector<uint32_t>& counts) : counts_(counts) {
    for (uint32_t c : counts_) total_ += c;
  }
  double total() const { return total_; }

  // The value below which a share q of the samples lies.
  double Quantile(double q) const {
    const double target = q * total_;
    double acc = 0;
    for (size_t b = 0; b < counts_.size(); ++b) {
      if (counts_[b] == 0) continue;
      const auto [lo, hi] = Interval(b);
      if (acc + counts_[b] >= target) return lo + (hi - lo) * (target - acc) / counts_[b];
      acc += counts_[b];
    }
    return static_cast<double>(counts_.size()) - 0.5;
  }

  // The median absolute deviation from `centre`: the d at which the samples within centre +- d make
  // half of them. Their number grows piecewise linearly with d; bisection to 1e-4 DN.
  double MedianAbsoluteDeviation(double centre) const {
    const auto within = [&](double d) {
      double n = 0;
      const auto first = static_cast<size_t>(std::max(0.0, std::floor(centre - d)));
      const auto last = std::min(counts_.size() - 1, static_cast<size_t>(std::max(0.0, std::ceil(centre + d))));
      for (size_t b = first; b <= last; ++b) {
        const auto [lo, hi] = Interval(b);
        n += counts_[b] * std::max(0.0, std::min(hi, centre + d) - std::max(lo, centre - d));
      }
      return n;
    };
    double lo = 0, hi = 1;
    while (within(hi) < 0.5 * total_ && hi < static_cast<double>(counts_.size())) hi *= 2;
    for (int it = 0; it < 60 && hi - lo > 1e-4; ++it) {
      const double mid = 0.5 * (lo + hi);
      (within(mid) < 0.5 * total_ ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
  }

 private:
  // Bin 0 holds no negative values: the clipped ones of an unsigned image, or |d| in [0, 1/2] for a histogram of
  // absolute differences.
  static std::pair<double, double> Interval(size_t b) {
    const double v = static_cast<double>(b);
    return {b == 0 ? 0.0 : v - 0.5, v + 0.5};
  }
  const std::vector<uint32_t>& counts_;
  double total_ = 0;
};

// 1.4826 MAD / sqrt 2 of the differences of adjacent pixels, from their histogram (integer images).
double DifferenceSigmaOf(const std::vector<uint32_t>& hist) {
  const SpreadHistogram h(hist);
  if (h.total() == 0) return 0;
  return kMadToSigma * h.Quantile(0.5) / std::sqrt(2.0);
}

// The same of a float image's pairs (FrameSummary counts an integer frame's).
double FloatDifferenceSigma(const cv::Mat& img) {
  std::vector<float> d;
  for (int r = 0; r < img.rows; r += 4) {
    const auto* p = img.ptr<float>(r);
    for (int c = 0; c + 1 < img.cols; c += 2) d.push_back(std::abs(p[c + 1] - p[c]));
  }
  if (d.empty()) return 0;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return kMadToSigma * d[d.size() / 2] / std::sqrt(2.0);
}

// The negative log-likelihood of a histogram's core as the rounded samples of a Gaussian (mean p[0], sigma
// e^p[1]), its counts merged into cells of `width` values (a few per sigma: the cost then does not grow with the
// noise of a 16-bit frame): cell j holds the values first + j width ... + width - 1, probability
// Phi((hi + 1/2 - mu) / sigma) - Phi((lo - 1/2 - mu) / sigma); value 0 takes everything below 1/2 and the top value
// everything above its lower edge (an unsigned image clips there). The likelihood is that of the cells given that
// a sample fell in them (truncated), so the spots' light beyond the core does not count.
struct RoundedGaussianCore {
  std::vector<double> counts;  // per cell
  int first = 0, width = 1, top = 0;
  template <typename T>
  bool operator()(const T* p, T* cost) const {
    const T sigma = exp(p[1]);
    const auto below = [&](int value) {  // P(sample rounds to < value)
      if (value <= 0) return T(0);
      if (value > top) return T(1);
      return T(0.5) * erfc(-(T(value - 0.5) - p[0]) / (sigma * T(M_SQRT2)));
    };
    T log_likelihood(0), n(0);
    const int cells = static_cast<int>(counts.size());
    for (int j = 0; j < cells; ++j) {
      const int lo = first + j * width;
      if (counts[j] > 0) log_likelihood += T(counts[j]) * log(below(lo + width) - below(lo) + T(1e-300));
      n += T(counts[j]);
    }
    const T core = below(first + cells * width) - below(first);
    *cost = -(log_likelihood - n * log(core + T(1e-300)));
    return true;
  }
};

// The read noise of an integer image's background by maximum likelihood on the histogram's core (the median +- 3
// spread sigmas): exact for the rounded Gaussian where the spread MAD is not — below ~1 DN, where rounding is not a
// uniform smear, and with the background within 2 sigmas of zero, where the image clips. Falls back to the spread
// estimate (less the quantisation) when the fit fails. Written with Ceres' gradient solver; the likelihood of binned
// data is not a least-squares problem.
double MaximumLikelihoodReadNoise(const std::vector<uint32_t>& hist, double median, double spread_sigma) {
  const double fallback = std::sqrt(std::max(0.0, spread_sigma * spread_sigma - 1.0 / 12.0));
  const double reach = std::max(2.0, 3.0 * spread_sigma);
  const int top = static_cast<int>(hist.size()) - 1;
  RoundedGaussianCore core;
  core.top = top;
  core.width = std::max(1, static_cast<int>(spread_sigma / 4.0));
  core.first = std::clamp(static_cast<int>(std::floor(median - reach)), 0, top);
  const int last = std::clamp(static_cast<int>(std::ceil(median + reach)), 0, top);
  for (int lo = core.first; lo + core.width - 1 <= last; lo += core.width) {
    double c = 0;
    for (int v = lo; v < lo + core.width; ++v) c += hist[v];
    core.counts.push_back(c);
  }
  if (core.counts.size() < 3) return fallback;
  double p[2] = {median, std::log(std::max(0.2, fallback))};
  ceres::GradientProblem problem(new ceres::AutoDiffFirstOrderFunction<RoundedGaussianCore, 2>(
      new RoundedGaussianCore(std::move(core))));
  ceres::GradientProblemSolver::Options options;
  options.max_num_iterations = 100;
  options.logging_type = ceres::SILENT;
  ceres::GradientProblemSolver::Summary summary;
  ceres::Solve(options, problem, p, &summary);
  const double sigma = std::exp(p[1]);
  if (!summary.IsSolutionUsable() || !std::isfinite(sigma) || sigma > 2 * reach) return fallback;
  return sigma;
}

BackgroundStats IntegerStats(const std::vector<uint32_t>& hist) {
  BackgroundStats s;
  const SpreadHistogram h(hist);
  if (h.total() == 0) return s;
  s.median = h.Quantile(0.5);
  s.bright = h.Quantile(0.9999);
  s.sigma = kMadToSigma * h.MedianAbsoluteDeviation(s.median);
  return s;
}

BackgroundStats FloatStats(const cv::Mat& img) {
  std::vector<float> v;
  v.reserve(static_cast<size_t>(img.rows / 2 + 1) * (img.cols / 2 + 1));
  for (int r = 0; r < img.rows; r += 2) {
    const auto* p = img.ptr<float>(r);
    for (int c = 0; c < img.cols; c += 2) v.push_back(p[c]);
  }
  BackgroundStats s;
  if (v.empty()) return s;
  const auto pct = [&v](double q) {
    const auto k = static_cast<size_t>(std::clamp(q, 0.0, 1.0) * (v.size() - 1));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return static_cast<double>(v[k]);
  };
  s.bright = pct(0.9999);
  s.median = pct(0.5);
  for (auto& x : v) x = std::abs(x - static_cast<float>(s.median));
  s.sigma = kMadToSigma * pct(0.5);
  return s;
}

// The read noise from the histogram of the pixels on every 4th row, every 2nd column, where `free_half` (on
// the background's subsample grid, every 2nd row and column) is set — or of all of them when fewer than 10,000
// are (750,000 pixels on a 12 MP frame: ample for one number, half the cost of the full subsample).
template <typename T>
double ReadNoiseOutside(const cv::Mat& img, const cv::Mat& free_half) {
  std::vector<uint32_t> hist(sizeof(T) == 1 ? 256 : 65536, 0);
  const auto fill = [&](bool everywhere) {
    size_t n = 0;
    for (int r = 0; r < img.rows; r += 4) {
      const T* p = img.ptr<T>(r);
      const uint8_t* f = free_half.ptr<uint8_t>(r / 2);
      for (int c = 0; c < img.cols; c += 2) {
        if (everywhere || f[c / 2]) {
          ++hist[p[c]];
          ++n;
        }
      }
    }
    return n;
  };
  if (fill(false) < 10000) {
    std::fill(hist.begin(), hist.end(), 0);
    fill(true);
  }
  const SpreadHistogram h(hist);
  if (h.total() == 0) return 0;
  const double median = h.Quantile(0.5);
  return MaximumLikelihoodReadNoise(hist, median, kMadToSigma * h.MedianAbsoluteDeviation(median));
}

}  // namespace

double ReadNoiseAwayFrom(const cv::Mat& image, const std::vector<cv::Rect>& occupied, int margin_px,
                         double whole_frame) {
  if (image.depth() != CV_8U && image.depth() != CV_16U) return whole_frame;  // float: no rounding to model
  // A mask on the background's subsample grid (every 2nd pixel of every 2nd row).
  cv::Mat free_half((image.rows + 1) / 2, (image.cols + 1) / 2, CV_8U, cv::Scalar(1));
  for (const cv::Rect& r : occupied) {
    const int grow = std::max(margin_px, std::max(r.width, r.height) / 2);
    const cv::Rect grown(r.x - grow, r.y - grow, r.width + 2 * grow, r.height + 2 * grow);
    const cv::Rect half(grown.x / 2, grown.y / 2, (grown.width + 3) / 2, (grown.height + 3) / 2);
    free_half(half & cv::Rect(0, 0, free_half.cols, free_half.rows)).setTo(0);
  }
  return image.depth() == CV_8U ? ReadNoiseOutside<uint8_t>(image, free_half)
                                : ReadNoiseOutside<uint16_t>(image, free_half);
}

BackgroundStats BackgroundOf(const FrameSummary& summary) {
  BackgroundStats s = IntegerStats(summary.values());
  s.sigma_diff = DifferenceSigmaOf(summary.differences());
  return s;
}

BackgroundStats MeasureBackground(const cv::Mat& image) {
  BackgroundStats s = FloatStats(image);
  s.sigma_diff = FloatDifferenceSigma(image);
  return s;
}

double QuantisationVariance(const cv::Mat& image) { return image.depth() == CV_32F ? 0.0 : 1.0 / 12.0; }

}  // namespace topocal::correct::detail
