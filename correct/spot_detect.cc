#include "correct/spot_detect.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <type_traits>

#include <ceres/ceres.h>
#include <ceres/tiny_solver.h>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "correct/background_stats.h"
#include "correct/frame_summary.h"
#include "correct/spot_detail.h"
#include "util/io.h"

namespace topocal::correct {
namespace {

using detail::At;
using detail::DeblendMerged;
using detail::KeepNearestPixels;
using detail::Component;
using detail::RefineByGaussianFit;
using detail::RefineByPsfFit;
using detail::Saturates;

// The local background where it rises above the global one: skin of a lid, the lid's margin, a bright iris or
// sclera behind the pattern. The floor of the image in 8 x 8 blocks (the darkest pixel of each), its minimum over
// the 3 x 3 blocks around (a 24 px window: wider than a spot and its neighbours' gap), smoothed, plus the floor's
// bias below the mean (kFloorBiasSigmas noise sigmas). Written here because OpenCV has no block-minimum reduction;
// cv::erode over the full frame costs several times more for the same floor.
// Pixels above the global threshold stay foreground only if they are also above this background plus the same
// margin the global threshold keeps above the global background. Where the floor is within kLocalSigmas of the
// global background (a uniform frame), the global threshold stands unchanged.
constexpr int kBlockPx = 8;
constexpr double kFloorBiasSigmas = 3.0, kLocalSigmas = 4.0;

template <typename T>
cv::Mat BlockFloor(const cv::Mat& image) {
  const int rows = (image.rows + kBlockPx - 1) / kBlockPx, cols = (image.cols + kBlockPx - 1) / kBlockPx;
  cv::Mat floor(rows, cols, CV_32FC1, cv::Scalar(std::numeric_limits<float>::max()));
  for (int r = 0; r < image.rows; ++r) {
    const T* p = image.ptr<T>(r);
    float* f = floor.ptr<float>(r / kBlockPx);
    for (int c = 0; c < image.cols; ++c) f[c / kBlockPx] = std::min(f[c / kBlockPx], static_cast<float>(p[c]));
  }
  return floor;
}

// Clears the foreground pixels of `mask` (inside `box`) that do not stand above the local background; returns false
// (mask untouched) where the background is uniform.
bool ApplyLocalBackground(const cv::Mat& image, double median, double sigma, double above_bg, const cv::Rect& box,
                          cv::Mat* mask) {
  cv::Mat floor = image.depth() == CV_8U    ? BlockFloor<uint8_t>(image)
                  : image.depth() == CV_16U ? BlockFloor<uint16_t>(image)
                                            : BlockFloor<float>(image);
  cv::erode(floor, floor, cv::Mat::ones(3, 3, CV_8U));
  cv::blur(floor, floor, cv::Size(3, 3));
  const float lift = static_cast<float>(kFloorBiasSigmas * sigma);
  const float uniform = static_cast<float>(median + kLocalSigmas * sigma);
  bool any = false;
  for (int r = 0; r < floor.rows && !any; ++r) {
    const float* f = floor.ptr<float>(r);
    for (int c = 0; c < floor.cols; ++c) any |= f[c] + lift > uniform;
  }
  if (!any) return false;
  for (int r = box.y; r < box.y + box.height; ++r) {
    uint8_t* m = mask->ptr<uint8_t>(r);
    const float* f = floor.ptr<float>(r / kBlockPx);
    for (int c = box.x; c < box.x + box.width; ++c) {
      if (!m[c]) continue;
      const double local = f[c / kBlockPx] + lift;
      if (local <= uniform) continue;
      const double value = image.depth() == CV_8U    ? image.ptr<uint8_t>(r)[c]
                           : image.depth() == CV_16U ? image.ptr<uint16_t>(r)[c]
                                                     : image.ptr<float>(r)[c];
      if (value <= local + above_bg) m[c] = 0;
    }
  }
  return true;
}

// Whether any pixel of a float image is above `threshold` (rounded to float), as cv::compare(image, threshold,
// CMP_GT) has it, without a frame-sized mask: band by band, stopping at the band that holds one; a NaN is above no
// threshold. An integer frame asks its FrameSummary (the maxima of the same bands).
bool AnyAboveFloat(const cv::Mat& image, double threshold) {
  const auto limit = static_cast<float>(threshold);
  constexpr int kBand = detail::FrameSummary::kBandRows;
  for (int r = 0; r < image.rows; r += kBand) {
    cv::Mat above;
    cv::compare(image.rowRange(r, std::min(image.rows, r + kBand)), limit, above, cv::CMP_GT);
    if (cv::countNonZero(above) > 0) return true;
  }
  return false;
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

const cv::Mat& Disc(int radius) {
  static thread_local std::vector<cv::Mat> cache;
  if (static_cast<int>(cache.size()) <= radius) cache.resize(radius + 1);
  if (cache[radius].empty()) {
    cache[radius] = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
  }
  return cache[radius];
}

// A window's own background: a plane fitted by least squares to the window's outer edge (its pixels 3 px beyond the
// spot's threshold contour, less those on a line shared with a neighbour and those of other blobs). An iris, a
// skin's level or a slope under the spot then leaves the centroid (a constant or a plane subtracted from a window
// about the spot moves its centroid only by what the plane misses). residual_dn: the edge pixels' rms about the
// plane — the background's structure that no plane describes (a lid margin, a lash's edge, a neighbour's light).
// Fewer than 8 edge pixels: the global background, residual 0.
struct LocalBackground {
  double b0 = 0, bu = 0, bv = 0, u0 = 0, v0 = 0;
  double residual_dn = 0;
  double At(double u, double v) const { return b0 + bu * (u - u0) + bv * (v - v0); }
};

constexpr double kUnevenPeakShare = 0.03, kUnevenNoiseSigmas = 6.0;
constexpr double kOwnBackgroundSigmas = 4.0, kOwnBackgroundPeakShare = 0.05;

LocalBackground WindowBackground(const cv::Mat& image_box, const cv::Mat& labels, const Component& comp,
                                 const cv::Mat& uncut, double bg) {
  LocalBackground out;
  out.b0 = bg;
  cv::Mat inner;
  cv::erode(uncut, inner, cv::Mat::ones(3, 3, CV_8U), cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  const cv::Mat edge = uncut & ~inner & comp.window;
  std::vector<Eigen::Vector3d> px;  // u, v, value
  for (int r = 0; r < edge.rows; ++r) {
    const uint8_t* e = edge.ptr<uint8_t>(r);
    const int* lab = labels.ptr<int>(r + comp.roi.y) + comp.roi.x;
    for (int c = 0; c < edge.cols; ++c) {
      if (e[c] && lab[c] == 0) {
        px.emplace_back(c + comp.roi.x, r + comp.roi.y, At(image_box, r + comp.roi.y, c + comp.roi.x));
      }
    }
  }
  if (px.size() < 8) return out;
  out.u0 = comp.roi.x + 0.5 * (comp.roi.width - 1);
  out.v0 = comp.roi.y + 0.5 * (comp.roi.height - 1);
  Eigen::Matrix3d n = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const auto& p : px) {
    const Eigen::Vector3d a(1.0, p.x() - out.u0, p.y() - out.v0);
    n += a * a.transpose();
    b += a * p.z();
  }
  const Eigen::Vector3d x = n.ldlt().solve(b);
  if (!x.allFinite()) return out;
  out.b0 = x(0);
  out.bu = x(1);
  out.bv = x(2);
  double ss = 0;
  for (const auto& p : px) ss += std::pow(p.z() - out.At(p.x(), p.y()), 2);
  out.residual_dn = std::sqrt(ss / px.size());
  return out;
}

// What the per-component work needs of the segmentation (box coordinates).
struct Segmentation {
  const cv::Mat& image_box;
  const cv::Mat& labels;
  const cv::Mat& stats;
  cv::Rect box;           // the box in the image
  cv::Size image_size;
  double bg = 0, threshold_sigma = 0;
  bool uneven_frame = false;
};

// The labels of the other components (of at least min_area px) within `reach` of component k: the component grown
// by `reach` (a disc) and looked through. Sorted.
std::vector<int> NeighboursWithinGap(const cv::Mat& labels, const cv::Mat& stats, int k, int reach, int min_area) {
  const int left = stats.at<int>(k, cv::CC_STAT_LEFT), top = stats.at<int>(k, cv::CC_STAT_TOP);
  const int width = stats.at<int>(k, cv::CC_STAT_WIDTH), height = stats.at<int>(k, cv::CC_STAT_HEIGHT);
  const cv::Rect wide = cv::Rect(left - reach, top - reach, width + 2 * reach, height + 2 * reach) &
                        cv::Rect(0, 0, labels.cols, labels.rows);
  cv::Mat grown = labels(wide) == k;
  if (reach > 0) cv::dilate(grown, grown, Disc(reach));
  std::vector<int> out;
  for (int r = 0; r < wide.height; ++r) {
    const int* lab = labels.ptr<int>(r + wide.y) + wide.x;
    const uint8_t* gr = grown.ptr<uint8_t>(r);
    for (int c = 0; c < wide.width; ++c) {
      if (gr[c] && lab[c] != 0 && lab[c] != k && stats.at<int>(lab[c], cv::CC_STAT_AREA) >= min_area &&
          std::find(out.begin(), out.end(), lab[c]) == out.end()) {
        out.push_back(lab[c]);
      }
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Component k (of an accepted area): its window, neighbours, flags and centroid (steps 4-5 of spot_detect.h).
// nullopt when the window holds no light above its background.
std::optional<Component> MakeComponent(const Segmentation& seg, int k, const SpotDetectionOptions& options) {
  const cv::Mat& image_box = seg.image_box;
  const cv::Mat& labels = seg.labels;
  const cv::Mat& stats = seg.stats;
  const cv::Rect& box = seg.box;
  const double bg = seg.bg, threshold_sigma = seg.threshold_sigma;
  const bool uneven_frame = seg.uneven_frame;
  const int m = options.window_margin_px;
  const int area = stats.at<int>(k, cv::CC_STAT_AREA);
  const int left = stats.at<int>(k, cv::CC_STAT_LEFT), top = stats.at<int>(k, cv::CC_STAT_TOP);
  const int right = left + stats.at<int>(k, cv::CC_STAT_WIDTH) - 1, bottom = top + stats.at<int>(k, cv::CC_STAT_HEIGHT) - 1;
  const int c0 = std::max(0, left - m);
  const int r0 = std::max(0, top - m);
  const int c1 = std::min(image_box.cols - 1, right + m);
  const int r1 = std::min(image_box.rows - 1, bottom + m);
  Component comp;
  comp.label = k;
  // The window: the component grown by `m` pixels (a disc kernel), other components excluded. Following the
  // spot's own outline rather than its bounding box keeps the far window corners — pure noise with the largest
  // lever arm — out of the centroid.
  comp.roi = cv::Rect(c0, r0, c1 - c0 + 1, r1 - r0 + 1);
  comp.window = labels(comp.roi) == k;
  if (m > 0) cv::dilate(comp.window, comp.window, Disc(m));
  unsigned flags = 0;
  // Cut by the image's border (the box never cuts a window that the image does not: it is grown by m + 1).
  if (left + box.x - m < 0 || top + box.y - m < 0 || right + box.x + m > seg.image_size.width - 1 ||
      bottom + box.y + m > seg.image_size.height - 1) {
    flags |= kTruncated;
  }
  // The other components within the gap of the window; the window then keeps only the pixels nearer to this spot.
  comp.neighbours = NeighboursWithinGap(labels, stats, k, m + options.near_blob_gap_px, options.min_area_px);
  const cv::Mat uncut = comp.window.clone();
  if (!comp.neighbours.empty()) KeepNearestPixels(labels, m, &comp);
  double peak = 0;
  std::vector<double>& values = comp.values;
  thread_local std::vector<Eigen::Vector3d> window;  // u, v, value of the window's pixels
  window.clear();
  for (int r = r0; r <= r1; ++r) {
    const int* lab = labels.ptr<int>(r);
    const uint8_t* win = comp.window.ptr<uint8_t>(r - r0) - c0;
    for (int c = c0; c <= c1; ++c) {
      if (!win[c] || (lab[c] != 0 && lab[c] != k)) continue;
      const double value = At(image_box, r, c);
      if (Saturates(image_box, value)) flags |= kSaturated;
      const double w = value - bg;
      peak = std::max(peak, w);
      if (lab[c] == k) values.push_back(w);
      window.emplace_back(c, r, value);
    }
  }
  const LocalBackground local = WindowBackground(image_box, labels, comp, uncut, bg);
  // The window's own background where its level departs from the global one by more than the spot's own tails
  // can lift the window's edge (kOwnBackgroundPeakShare of its peak: 0.7 % at the edge of a spot blurred by 2 px)
  // and by more than kOwnBackgroundSigmas pixel noise sigmas — an iris, skin — or where the whole frame's
  // background is uneven. Elsewhere the edge is the spot's own tail, and a plane fitted to it would bias the
  // centroid (measured: 4x the error on 2 px PSF spots).
  const bool own_background = uneven_frame || std::abs(local.b0 - bg) > std::max(kOwnBackgroundSigmas * threshold_sigma,
                                                                                kOwnBackgroundPeakShare * peak);
  if (local.residual_dn > kUnevenPeakShare * peak + kUnevenNoiseSigmas * threshold_sigma) flags |= kUnevenBackground;
  // The centroid above the window's own background (or the global one); the flux above the global background
  // (the PSF fit's scale, which fits its own background level).
  double sw = 0, su = 0, sv = 0, flux = 0;
  for (const auto& p : window) {
    const double w = p.z() - (own_background ? local.At(p.x(), p.y()) : bg);
    flux += p.z() - bg;
    sw += w;
    su += w * p.x();
    sv += w * p.y();
  }
  if (!(sw > 0) || !(flux > 0)) return std::nullopt;
  DetectedSpot& s = comp.spot;
  s.centre_px = {su / sw, sv / sw};
  s.flux_dn = flux;
  s.peak_dn = peak;
  s.area_px = area;
  s.flags = flags;
  return comp;
}

// kNearBlob on the spots whose window was split with a neighbour that is not a like spot: a blob left out (too
// large: a lid margin, a lash's glint) or one whose light above background differs by more than a factor
// kLikeFluxRatio from the spot's own (a glint, a spot cut by a lash). Between like spots the split leaves the
// centre unbiased (KeepNearestPixels); next to an unlike blob it does not, and the spot is flagged.
void FlagUnlikeNeighbours(int label_count, std::vector<Component>* comps) {
  constexpr double kLikeFluxRatio = 2.0;
  std::vector<double> core(label_count, -1.0);  // the component's own light above background; -1: not a spot
  for (const auto& comp : *comps) {
    double sum = 0;
    for (double v : comp.values) sum += v;
    core[comp.label] = sum;
  }
  for (auto& comp : *comps) {
    const double own = core[comp.label];
    for (int other : comp.neighbours) {
      const double theirs = core[other];
      if (!(theirs > 0) || !(own > 0) || theirs > kLikeFluxRatio * own || own > kLikeFluxRatio * theirs) {
        comp.spot.flags |= kNearBlob;
        break;
      }
    }
  }
}

}  // namespace

std::string SpotFlagsText(unsigned flags) {
  std::string out;
  const auto add = [&out](const char* s) { out += out.empty() ? s : std::string("|") + s; };
  if (flags & kNearBlob) add("near_blob");
  if (flags & kSaturated) add("saturated");
  if (flags & kTruncated) add("truncated");
  if (flags & kFluxOutlier) add("flux_outlier");
  if (flags & kUnevenBackground) add("uneven_background");
  if (flags & kSurfaceOutlier) add("surface_outlier");
  if (flags & kSurfaceLabelled) add("surface_labelled");
  return out;
}

bool SpotDetectionOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string m) {
    if (why) *why = std::move(m);
    return false;
  };
  if (!(threshold_sigmas > 0)) return fail("threshold_sigmas must be > 0");
  if (!(threshold_fraction >= 0 && threshold_fraction < 1)) return fail("threshold_fraction must be in [0, 1)");
  if (min_area_px < 1 || max_area_px < min_area_px) return fail("need 1 <= min_area_px <= max_area_px");
  if (window_margin_px < 0) return fail("window_margin_px must be >= 0");
  if (!(gain_e_per_dn >= 0) || !std::isfinite(gain_e_per_dn)) return fail("gain_e_per_dn must be >= 0 (0: estimate)");
  if (!(read_noise_dn >= 0) || !std::isfinite(read_noise_dn)) return fail("read_noise_dn must be >= 0 (0: estimate)");
  if (near_blob_gap_px < 0) return fail("near_blob_gap_px must be >= 0");
  return true;
}

namespace {

// The sensor's read noise (quantisation excluded) into *out: on a uniform frame the histogram's own, of the pixels
// away from every component (`stats`, box coordinates); where a skin or an iris widens the histogram, the
// adjacent-pixel differences' (less the quantisation they include: two roundings, and the spread of the
// difference's own integer value).
void MeasureReadNoise(const cv::Mat& image, const detail::BackgroundStats& st, bool uneven_frame, const cv::Mat& stats,
                      const cv::Rect& box, const SpotDetectionOptions& options, SpotDetection* out) {
  if (options.read_noise_dn > 0) {
    out->read_noise_dn = options.read_noise_dn;
    out->read_noise_source = "given";
    return;
  }
  if (uneven_frame) {
    out->read_noise_dn =
        std::sqrt(std::max(0.0, st.sigma_diff * st.sigma_diff - 1.5 * detail::QuantisationVariance(image)));
    out->read_noise_source =
        "adjacent-pixel differences (the background is not uniform: a texture at the pixel scale, such as skin or "
        "an iris, counts as noise, so this is an upper bound)";
    return;
  }
  std::vector<cv::Rect> occupied;
  for (int k = 1; k < stats.rows; ++k) {
    occupied.emplace_back(stats.at<int>(k, cv::CC_STAT_LEFT) + box.x, stats.at<int>(k, cv::CC_STAT_TOP) + box.y,
                          stats.at<int>(k, cv::CC_STAT_WIDTH), stats.at<int>(k, cv::CC_STAT_HEIGHT));
  }
  out->read_noise_dn = detail::ReadNoiseAwayFrom(image, occupied, options.window_margin_px, st.sigma);
  out->read_noise_source = "the background's histogram away from the spots (uniform frame)";
}

// A frame's background, and whether any pixel is above a threshold: an integer frame's from its FrameSummary (one
// pass over the frame), a float frame's from its pixels.
class FrameStatistics {
 public:
  explicit FrameStatistics(const cv::Mat& image) : image_(image) {
    if (image_.type() != CV_32FC1) summary_ = detail::FrameSummary::Of(image_);
  }
  detail::BackgroundStats Background() const {
    return summary_ ? detail::BackgroundOf(*summary_) : detail::MeasureBackground(image_);
  }
  bool AnyAbove(double threshold_dn) const {
    return summary_ ? summary_->AnyAbove(threshold_dn) : AnyAboveFloat(image_, threshold_dn);
  }

 private:
  const cv::Mat& image_;
  std::optional<detail::FrameSummary> summary_;
};

void CheckDetectionInput(const cv::Mat& image, const SpotDetectionOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError("DetectSpots: " + why);
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F)) {
    throw util::InputError("DetectSpots: the image must be one channel of 8-bit, 16-bit or float pixels");
  }
}

}  // namespace

SpotDetection DetectSpots(const cv::Mat& image, const SpotDetectionOptions& options) {
  CheckDetectionInput(image, options);
  SpotDetection out;
  out.gain_source = options.method == CentroidMethod::kWeightedPsfFit
                        ? "not measured: no spot"
                        : "not measured: only the psf estimator uses a noise model";
  if (image.empty()) return out;
  const FrameStatistics frame_statistics(image);
  const detail::BackgroundStats st = frame_statistics.Background();
  // The threshold's noise: the smaller estimate (equal on a uniform frame; the difference-based one where a
  // smooth background change widens the histogram). An integer image's difference MAD can be 0 at < 1 DN noise.
  const double threshold_sigma = st.sigma_diff > 0 ? std::min(st.sigma, st.sigma_diff) : st.sigma;
  out.background_dn = st.median;
  out.noise_dn = st.sigma;
  const bool uneven_frame = st.sigma > 1.5 * threshold_sigma;
  const double q = detail::QuantisationVariance(image);
  out.threshold_dn = st.median + std::max(options.threshold_sigmas * threshold_sigma,
                                          options.threshold_fraction * (st.bright - st.median));
  if (!frame_statistics.AnyAbove(out.threshold_dn)) return out;
  cv::Mat full_mask;
  cv::compare(image, out.threshold_dn, full_mask, cv::CMP_GT);
  cv::Rect box = ForegroundBox(full_mask, options.window_margin_px + 1);
  if (box.empty()) return out;
  // A background that is not uniform shows as a histogram wider than the pixel-to-pixel noise; only then is the
  // local background worth its pass over the frame, and each window's own background subtracted in the centroid
  // (on a uniform frame its estimate would only add noise).
  if (options.local_background && uneven_frame &&
      ApplyLocalBackground(image, st.median, threshold_sigma, out.threshold_dn - st.median,
                           box & cv::Rect(0, 0, image.cols, image.rows), &full_mask)) {
    box = ForegroundBox(full_mask, options.window_margin_px + 1);
    if (box.empty()) return out;
  }
  // From here on everything is in the box's coordinates; centres are shifted back at the end.
  const cv::Mat image_box = image(box);
  cv::Mat labels, stats, centroids;
  cv::connectedComponentsWithStats(full_mask(box), labels, stats, centroids, 8, CV_32S);
  MeasureReadNoise(image, st, uneven_frame, stats, box, options, &out);
  const double bg = out.background_dn;
  DeblendMerged(image_box, out.threshold_dn, threshold_sigma, options, &labels, &stats);
  const int n = stats.rows;
  const Segmentation seg{image_box, labels, stats, box, image.size(), bg, threshold_sigma, uneven_frame};
  std::vector<Component> comps;
  comps.reserve(n);
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
    if (auto comp = MakeComponent(seg, k, options)) comps.push_back(std::move(*comp));
  }
  FlagUnlikeNeighbours(n, &comps);
  if (options.method == CentroidMethod::kGaussianFit) {
    RefineByGaussianFit(image_box, labels, bg, &comps);
  } else if (options.method == CentroidMethod::kWeightedPsfFit) {
    const double read_var = out.read_noise_dn * out.read_noise_dn + q;
    const detail::NoiseModelFit fit =
        RefineByPsfFit(image_box, labels, bg, out.threshold_dn, read_var, options.gain_e_per_dn, &comps);
    out.gain_e_per_dn = fit.gain_e_per_dn;
    out.gain_measured = fit.gain_measured;
    out.gain_evidence_spots = fit.evidence_spots;
    out.gain_source = options.gain_e_per_dn > 0 ? "given"
                      : fit.gain_measured
                          ? fmt::format("measured from {} spots", fit.evidence_spots)
                          : fmt::format("not measured: {} spots gave clean evidence, {} needed; read noise only",
                                        fit.evidence_spots, detail::kMinGainEvidenceSpots);
  }
  for (auto& comp : comps) {
    comp.spot.centre_px += Eigen::Vector2d(box.x, box.y);
    out.spots.push_back(comp.spot);
  }
  return out;
}

}  // namespace topocal::correct
