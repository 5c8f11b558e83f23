// Segmentation's deblending (spot_detect.h, step 4): merged spots split at a second threshold, and close neighbours'
// windows cut along the line of equal distance.
#include "correct/spot_detail.h"

#include <algorithm>
#include <limits>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace topocal::correct::detail {
namespace {

// For every pixel of `seeds` (CV_32S: a label > 0 on seed pixels, 0 elsewhere), the label of the nearest seed pixel
// (0 where there is none): cv::distanceTransform's pixel labels (DIST_LABEL_PIXEL), mapped back to the seeds' labels.
cv::Mat NearestSeed(const cv::Mat& seeds) {
  cv::Mat distance, nearest;
  cv::distanceTransform(seeds == 0, distance, nearest, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<int> owner;  // OpenCV's label of a seed pixel -> the seed's label
  for (int r = 0; r < seeds.rows; ++r) {
    const int* l = seeds.ptr<int>(r);
    const int* n = nearest.ptr<int>(r);
    for (int c = 0; c < seeds.cols; ++c) {
      if (l[c] == 0) continue;
      if (n[c] >= static_cast<int>(owner.size())) owner.resize(n[c] + 1, 0);
      owner[n[c]] = l[c];
    }
  }
  for (int r = 0; r < nearest.rows; ++r) {
    int* n = nearest.ptr<int>(r);
    for (int c = 0; c < nearest.cols; ++c) n[c] = n[c] >= 0 && n[c] < static_cast<int>(owner.size()) ? owner[n[c]] : 0;
  }
  return nearest;
}

// A core of a merged blob rises this far above the level it is cut at: 6 noise sigmas and 15 % of the blob's height
// above the threshold (a noise ripple on a plateau does not).
constexpr double kCoreRiseNoiseSigmas = 6.0, kCoreRiseShare = 0.15;

// Whether component k holds two peaks that each rise `clear` above the saddle between them: its pixels flooded from
// the brightest down (union-find; a merge of two regions happens at their saddle's value); *peak its brightest. Cheap (one sort of the
// component's pixels), and never false where DeblendMerged's level test would split: two pieces that rise `clear`
// above a level are two regions whose saddle is below it. Only components for which it is true take the level test.
bool HasTwoPeaks(const cv::Mat& image_box, const cv::Mat& labels, const cv::Rect& rect, int k, double threshold_dn,
                 double noise_dn, double* peak) {
  const int w = rect.width, n = rect.width * rect.height;
  thread_local std::vector<std::pair<float, int>> order;
  thread_local std::vector<int> parent;
  thread_local std::vector<float> top;
  double brightest = -std::numeric_limits<double>::infinity();
  for (int r = rect.y; r < rect.y + rect.height; ++r) {
    const int* lab = labels.ptr<int>(r);
    for (int c = rect.x; c < rect.x + w; ++c) {
      if (lab[c] == k) brightest = std::max(brightest, At(image_box, r, c));
    }
  }
  *peak = brightest;
  const double clear = std::max(kCoreRiseNoiseSigmas * noise_dn, kCoreRiseShare * (brightest - threshold_dn));
  order.clear();
  for (int r = 0; r < rect.height; ++r) {
    const int* lab = labels.ptr<int>(r + rect.y) + rect.x;
    for (int c = 0; c < w; ++c) {
      if (lab[c] == k) order.emplace_back(static_cast<float>(At(image_box, r + rect.y, c + rect.x)), r * w + c);
    }
  }
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  parent.assign(n, -1);
  top.assign(n, 0.0f);
  const auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (const auto& [value, i] : order) {
    parent[i] = i;
    top[i] = value;
    const int r = i / w, c = i % w;
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if ((dr == 0 && dc == 0) || rr < 0 || cc < 0 || rr >= rect.height || cc >= w) continue;
        const int q = rr * w + cc;
        if (parent[q] < 0) continue;  // not flooded yet, or not this component's
        const int a = find(i), b = find(q);
        if (a == b) continue;
        if (std::min(top[a], top[b]) - value >= clear) return true;
        const int hi = top[a] >= top[b] ? a : b, lo = hi == a ? b : a;
        parent[lo] = hi;
      }
    }
  }
  return false;
}

// Component k (bounding box `rect`) split at its cores (labels in `pieces`, 0..piece_count - 1): the first core keeps
// label k, the others
// take new labels appended to `stats`; every other pixel of k goes to the nearest core (distance-transform labels).
void SplitIntoCores(const cv::Mat& pieces, int piece_count, const std::vector<int>& cores, int k, const cv::Rect& rect,
                    cv::Mat* labels, cv::Mat* stats) {
  // Core p keeps label k (the first) or takes a new one; the other pixels go to the nearest core.
  std::vector<int> core_label(piece_count, 0);
  for (size_t i = 0; i < cores.size(); ++i) core_label[cores[i]] = i == 0 ? k : stats->rows + static_cast<int>(i) - 1;
  cv::Mat seeds(rect.size(), CV_32SC1, cv::Scalar(0));
  for (int r = 0; r < rect.height; ++r) {
    for (int c = 0; c < rect.width; ++c) seeds.at<int>(r, c) = core_label[pieces.at<int>(r, c)];
  }
  const cv::Mat owner = NearestSeed(seeds);
  std::vector<cv::Rect> boxes(cores.size() + 1);
  std::vector<int> areas(cores.size() + 1, 0);
  const int first_new = stats->rows;
  for (int r = 0; r < rect.height; ++r) {
    int* lab = labels->ptr<int>(r + rect.y) + rect.x;
    for (int c = 0; c < rect.width; ++c) {
      if (lab[c] != k) continue;
      const int l = owner.at<int>(r, c) != 0 ? owner.at<int>(r, c) : k;
      lab[c] = l;
      const size_t slot = l == k ? 0 : static_cast<size_t>(l - first_new + 1);
      boxes[slot] |= cv::Rect(c + rect.x, r + rect.y, 1, 1);
      ++areas[slot];
    }
  }
  for (size_t slot = 0; slot < boxes.size(); ++slot) {
    const cv::Mat row = (cv::Mat_<int>(1, 5) << boxes[slot].x, boxes[slot].y, boxes[slot].width,
                         boxes[slot].height, areas[slot]);
    if (slot == 0) {
      row.copyTo(stats->row(k));
    } else {
      stats->push_back(row);
    }
  }
}

}  // namespace

// Restricts comp's window to the pixels nearer to its own component than to any other. Close neighbours then share
// the gap between them along the line of equal distance: each window holds its spot's light less the tail that
// crosses the line, plus the neighbour's tail that crosses it the other way — for neighbours of like brightness and
// size the mirror image of the first, so the two nearly cancel in the centre (docs/spot-noise.md has the figures).
// A distance transform of the window's surroundings labels every pixel with its nearest component pixel
// (cv::distanceTransform, DIST_LABEL_PIXEL); those labels are mapped back to the components'.
void KeepNearestPixels(const cv::Mat& labels, int margin, Component* comp) {
  const cv::Rect region = cv::Rect(comp->roi.x - margin, comp->roi.y - margin, comp->roi.width + 2 * margin,
                                   comp->roi.height + 2 * margin) &
                          cv::Rect(0, 0, labels.cols, labels.rows);
  const cv::Mat owner = NearestSeed(labels(region));
  const int du = comp->roi.x - region.x, dv = comp->roi.y - region.y;
  for (int r = 0; r < comp->window.rows; ++r) {
    uint8_t* w = comp->window.ptr<uint8_t>(r);
    const int* o = owner.ptr<int>(r + dv) + du;
    for (int c = 0; c < comp->window.cols; ++c) {
      if (w[c] && o[c] != comp->label) w[c] = 0;
    }
  }
}

// Splits the components that hold several spots merged above the threshold (defocus, a small sensor, a glint on a
// spot's flank): the component is thresholded again at rising levels, up to 5/7 of the way from the threshold to its
// peak; at the first level where it falls into two or more pieces of at least a tenth of its area (and min_area_px),
// the pieces become the spots' cores and the rest of the component goes to the nearest core (distance-transform
// labels, as KeepNearestPixels); each piece is examined again. A flat-topped spot's plateau lies above the highest level, so its noise cannot split
// it; two spots split when the saddle between them is below ~75 % of their level. The new components are appended
// to `labels` and `stats`.
void DeblendMerged(const cv::Mat& image_box, double threshold_dn, double noise_dn, const SpotDetectionOptions& options,
                   cv::Mat* labels, cv::Mat* stats) {
  constexpr int kLevels = 7, kHighestLevel = 5;
  constexpr int kMaxMergedSpots = 20;  // a whole defocused ring can merge: up to 20 spots' largest area
  // The pieces are examined again in turn (a defocused ring first splits into chains of spots): every split shrinks
  // the components, so the loop ends.
  for (int k = 1; k < stats->rows; ++k) {
    const int area = stats->at<int>(k, cv::CC_STAT_AREA);
    if (area < 4 * options.min_area_px || area > kMaxMergedSpots * options.max_area_px) continue;
    const cv::Rect rect(stats->at<int>(k, cv::CC_STAT_LEFT), stats->at<int>(k, cv::CC_STAT_TOP),
                        stats->at<int>(k, cv::CC_STAT_WIDTH), stats->at<int>(k, cv::CC_STAT_HEIGHT));
    double peak = 0;
    if (!HasTwoPeaks(image_box, *labels, rect, k, threshold_dn, noise_dn, &peak)) continue;  // the common case
    const double clear = std::max(kCoreRiseNoiseSigmas * noise_dn, kCoreRiseShare * (peak - threshold_dn));
    const cv::Mat own = (*labels)(rect) == k;
    cv::Mat values;
    image_box(rect).convertTo(values, CV_32F);
    for (int j = 1; j <= kHighestLevel; ++j) {
      const double level = threshold_dn + (peak - threshold_dn) * j / kLevels;
      cv::Mat above = (values > level) & own;
      cv::Mat pieces, piece_stats, piece_centres;
      const int count = cv::connectedComponentsWithStats(above, pieces, piece_stats, piece_centres, 8, CV_32S);
      int largest = 0;
      for (int p = 1; p < count; ++p) largest = std::max(largest, piece_stats.at<int>(p, cv::CC_STAT_AREA));
      // Each piece's peak above the level: a core must rise clear of the saddle, not by a noise ripple.
      std::vector<double> rise(count, 0.0);
      for (int r = 0; r < rect.height; ++r) {
        const int* pc = pieces.ptr<int>(r);
        const float* v = values.ptr<float>(r);
        for (int c = 0; c < rect.width; ++c) {
          if (pc[c] > 0) rise[pc[c]] = std::max(rise[pc[c]], v[c] - level);
        }
      }
      std::vector<int> cores;
      for (int p = 1; p < count; ++p) {
        const int a = piece_stats.at<int>(p, cv::CC_STAT_AREA);
        if (a >= options.min_area_px && 5 * a >= largest && rise[p] >= clear) cores.push_back(p);
      }
      if (cores.size() < 2) continue;
      SplitIntoCores(pieces, count, cores, k, rect, labels, stats);
      --k;  // this component again, now one piece
      break;
    }
  }
}

}  // namespace topocal::correct::detail
