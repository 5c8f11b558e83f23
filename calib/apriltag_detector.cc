#include "calib/apriltag_detector.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/LU>
#include <ceres/ceres.h>
#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "calib/apriltag_raii.h"

namespace topocal::calib {
namespace {

// Bits of a tag36h11 tag across its black square (libapriltag's width_at_border).
constexpr double kTagCells = 8.0;
// Corner regions left out of a side's strip: the other side's edge must be >= ~2.5 blur sigmas away.
constexpr double kCornerExclusionPx = 2.5;
constexpr double kMinStripHalfWidthPx = 1.5;
// A fitted edge further than this from libapriltag's side line is a failed fit (libapriltag's corners with
// refine_edges are within a few tenths of a pixel of the ink).
constexpr double kMaxEdgeOffsetPx = 2.0;
constexpr int kMinStripPixels = 12;
// Pixels deep in the strip this close (along the side) to a change of data-cell colour are left out.
constexpr double kDataEdgeClearancePx = 1.5;

// One pixel of the strip across a tag side. Across the side (n outwards, px) the tag's ink is: white gap (n > rho),
// the one-cell black border (rho - c < n < rho), then the data cell next to it, white (m = 1) or black (m = 0)
// as the tag's code says. Blurred by a Gaussian of sigma:
//   I = black + (white - black) * (Phi((n - rho) / sigma) + m * Phi((rho - c - n) / sigma))
// Modelling the inner data edge matters: at ~4 px cells and 1 px blur a white data cell lightens the thin black
// border and pulls an edge-only fit outwards by ~0.1 px.
struct EdgePixelResidual {
  EdgePixelResidual(double t, double n, double white_inside, double value)
      : t_(t), n_(n), white_inside_(white_inside), value_(value) {}
  template <typename T>
  bool operator()(const T* edge /* rho0, rho1 */, const T* photometric /* black, white, sigma, cell */,
                  T* residual) const {
    using std::erf;
    const T rho = edge[0] + T(t_) * edge[1];
    const T scale = T(1) / (photometric[2] * T(M_SQRT2));
    const T outer = T(0.5) * (T(1) + erf((T(n_) - rho) * scale));
    const T inner = T(0.5) * (T(1) + erf((rho - photometric[3] - T(n_)) * scale));
    residual[0] =
        photometric[0] + (photometric[1] - photometric[0]) * (outer + T(white_inside_) * inner) - T(value_);
    return true;
  }
  static ceres::CostFunction* Create(double t, double n, double white_inside, double value) {
    return new ceres::AutoDiffCostFunction<EdgePixelResidual, 1, 2, 4>(
        new EdgePixelResidual(t, n, white_inside, value));
  }

 private:
  double t_, n_, white_inside_, value_;
};

// A straight piece of ink edge fitted along part of a tag side: offset rho(a) from the detector's side line, for
// along-side distances a in [a_min, a_max] (t = (a - a_mid) / half-range in [-1, 1]).
struct EdgeFit {
  Eigen::Vector2d origin, along, normal;  // detector's side line; normal points out of the tag
  double a_mid = 0, half_range = 1;
  std::array<double, 2> rho{};
  double Offset(double a) const { return rho[0] + rho[1] * (a - a_mid) / half_range; }
  double OffsetSlope() const { return rho[1] / half_range; }
};

struct SideStrip {
  Eigen::Vector2d from, to, tag_centre;
  double cell_px = 0;   // bit-cell width across the side
  double inner_px = 0;  // strip extent into the tag
  double outer_px = 0;  // strip extent into the white gap
  std::array<uint8_t, 8> white_inside{};  // data cell next to the border, by cell index along the side
};

std::optional<EdgeFit> FitEdge(const cv::Mat& gray, const SideStrip& strip, double a_min, double a_max) {
  EdgeFit edge;
  edge.origin = strip.from;
  const double length = (strip.to - strip.from).norm();
  edge.along = (strip.to - strip.from) / length;
  edge.normal = Eigen::Vector2d(-edge.along.y(), edge.along.x());
  if (edge.normal.dot(0.5 * (strip.from + strip.to) - strip.tag_centre) < 0) edge.normal = -edge.normal;
  edge.a_mid = 0.5 * (a_min + a_max);
  edge.half_range = 0.5 * (a_max - a_min);
  if (!(edge.half_range > 1.0)) return std::nullopt;
  auto white_inside_at = [&](double a) {
    const int cell = std::clamp(static_cast<int>(std::floor(kTagCells * a / length)), 0, 7);
    return static_cast<double>(strip.white_inside[static_cast<size_t>(cell)]);
  };

  ceres::Problem problem;
  std::array<double, 4> photometric{};
  double dark_sum = 0, light_sum = 0;
  int dark = 0, light = 0, count = 0;
  const double reach = std::max(strip.inner_px, strip.outer_px) + 1.0;
  const Eigen::Vector2d p0 = strip.from + a_min * edge.along, p1 = strip.from + a_max * edge.along;
  const int x0 = std::max(0, static_cast<int>(std::floor(std::min(p0.x(), p1.x()) - reach)));
  const int x1 = std::min(gray.cols - 1, static_cast<int>(std::ceil(std::max(p0.x(), p1.x()) + reach)));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::min(p0.y(), p1.y()) - reach)));
  const int y1 = std::min(gray.rows - 1, static_cast<int>(std::ceil(std::max(p0.y(), p1.y()) + reach)));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d d = Eigen::Vector2d(x, y) - strip.from;
      const double a = d.dot(edge.along), n = d.dot(edge.normal);
      if (a < a_min || a > a_max || n < -strip.inner_px || n > strip.outer_px) continue;
      const double m = white_inside_at(a);
      const double value = gray.at<uint8_t>(y, x);
      // Starting levels: the middle of the black border and the outer half of the gap strip.
      if (n < -0.25 * strip.cell_px && n > -0.75 * strip.cell_px) { dark_sum += value; ++dark; }
      if (n > 0.5 * strip.outer_px) { light_sum += value; ++light; }
      // Deep inside, next to a change of data colour along the side, the ink is not a function of n alone.
      if (n < -0.5 * strip.cell_px &&
          (white_inside_at(a - kDataEdgeClearancePx) != m || white_inside_at(a + kDataEdgeClearancePx) != m)) {
        continue;
      }
      problem.AddResidualBlock(EdgePixelResidual::Create((a - edge.a_mid) / edge.half_range, n, m, value), nullptr,
                               edge.rho.data(), photometric.data());
      ++count;
    }
  }
  if (count < kMinStripPixels || dark == 0 || light == 0) return std::nullopt;
  photometric = {dark_sum / dark, light_sum / light, 1.0, strip.cell_px};
  if (!(photometric[1] - photometric[0] > 1.0)) return std::nullopt;  // no dark-to-light edge here
  problem.SetParameterLowerBound(photometric.data(), 2, 0.2);
  problem.SetParameterUpperBound(photometric.data(), 2, 0.5 * strip.cell_px + 1.0);
  problem.SetParameterLowerBound(photometric.data(), 3, 0.5 * strip.cell_px);
  problem.SetParameterUpperBound(photometric.data(), 3, 1.5 * strip.cell_px);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 50;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (!summary.IsSolutionUsable()) return std::nullopt;
  for (double a : {0.0, length}) {
    if (!(std::abs(edge.Offset(a)) < kMaxEdgeOffsetPx)) return std::nullopt;
  }
  return edge;
}

// The intersection of two fitted edges (lines), near `start`.
std::optional<Eigen::Vector2d> IntersectEdges(const EdgeFit& e1, const EdgeFit& e2, const Eigen::Vector2d& start) {
  // Each edge: normal . (x - origin) - Offset(along . (x - origin)) = 0, linear in x.
  Eigen::Matrix2d a;
  Eigen::Vector2d b;
  int row = 0;
  for (const EdgeFit* e : {&e1, &e2}) {
    const Eigen::Vector2d g = e->normal - e->OffsetSlope() * e->along;
    a.row(row) = g.transpose();
    b[row] = g.dot(e->origin) + e->rho[0] - e->OffsetSlope() * e->a_mid;
    ++row;
  }
  if (std::abs(a.determinant()) < 1e-3) return std::nullopt;  // (nearly) parallel edges
  const Eigen::Vector2d x = a.inverse() * b;
  if (!x.allFinite() || (x - start).norm() > 2 * kMaxEdgeOffsetPx) return std::nullopt;
  return x;
}

// Colour of the data cell next to the border along side k (corner k to corner k + 1, numbering of target.h), by
// cell index along the side; bitmap row-major, y down, 1 = black.
std::array<uint8_t, 8> WhiteInside(const std::vector<uint8_t>& bits, int cells, size_t side) {
  std::array<uint8_t, 8> white{};
  for (int i = 0; i < cells && i < 8; ++i) {
    int x = 0, y = 0;
    switch (side) {
      case 0: x = i; y = cells - 2; break;              // bottom-left -> bottom-right
      case 1: x = cells - 2; y = cells - 1 - i; break;  // bottom-right -> top-right
      case 2: x = cells - 1 - i; y = 1; break;          // top-right -> top-left
      default: x = 1; y = i; break;                     // top-left -> bottom-left
    }
    white[static_cast<size_t>(i)] = bits[static_cast<size_t>(y * cells + x)] ? 0 : 1;
  }
  return white;
}

std::optional<std::array<Eigen::Vector2d, 4>> RefineTag(const cv::Mat& gray, const std::array<Eigen::Vector2d, 4>& p,
                                                        const AprilGridLayout& grid, const std::vector<uint8_t>& bits,
                                                        int cells) {
  const Eigen::Vector2d centre = 0.25 * (p[0] + p[1] + p[2] + p[3]);
  std::array<double, 4> length{};
  for (size_t k = 0; k < 4; ++k) length[k] = (p[(k + 1) % 4] - p[k]).norm();
  // Each corner from the halves of its two sides next to it: lens distortion bends a side (sagitta ~0.1 px over
  // a 33 px tag near the image corner at k1 = -0.18), so a line through the near half is 4x closer to the curve.
  std::array<EdgeFit, 4> first_half, second_half;
  for (size_t k = 0; k < 4; ++k) {
    SideStrip strip;
    strip.from = p[k];
    strip.to = p[(k + 1) % 4];
    strip.tag_centre = centre;
    // Across side k the tag spans its neighbouring sides.
    strip.cell_px = 0.5 * (length[(k + 1) % 4] + length[(k + 3) % 4]) / kTagCells;
    const double gap_px = strip.cell_px * kTagCells * grid.tag_spacing_ratio;
    // One cell inwards (border + the data edge, modelled) and as far into the gap as the next tag's blurred edge
    // allows.
    strip.inner_px = std::max(kMinStripHalfWidthPx, strip.cell_px);
    strip.outer_px = std::max(kMinStripHalfWidthPx, std::min(strip.cell_px, gap_px - kCornerExclusionPx));
    strip.white_inside = WhiteInside(bits, cells, k);
    const double margin = kCornerExclusionPx + std::max(strip.inner_px, strip.outer_px);
    if (!(length[k] > 2 * margin + 4)) return std::nullopt;
    const auto a = FitEdge(gray, strip, margin, 0.6 * length[k]);
    const auto b = FitEdge(gray, strip, 0.4 * length[k], length[k] - margin);
    if (!a || !b) return std::nullopt;
    first_half[k] = *a;
    second_half[k] = *b;
  }
  std::array<Eigen::Vector2d, 4> refined;
  for (size_t k = 0; k < 4; ++k) {
    const auto corner = IntersectEdges(second_half[(k + 3) % 4], first_half[k], p[k]);
    if (!corner) return std::nullopt;
    refined[k] = *corner;
  }
  return refined;
}

}  // namespace

namespace {

// Corner k of tag t on the board (mm), as TargetDescription::CornerMm places it (calib/target.h).
cv::Point2d TagCornerMm(const AprilGridLayout& g, int t, int k) {
  const Eigen::Vector2d origin = g.TagOriginMm(t);
  const double s = g.tag_size_mm;
  const double dx[4] = {0, s, s, 0}, dy[4] = {s, s, 0, 0};
  return {origin.x() + dx[k], origin.y() + dy[k]};
}

// Neighbours a tag is judged by: the other tags within this many grid steps, and at least this many of them.
constexpr int kNeighbourSteps = 2;
constexpr int kMinNeighbourTags = 3;
// A corner further than this fraction of the tag's side from where its neighbours put it: the tag is not where the
// grid puts its id. A wrong id puts it at least one pitch (1 + tagSpacing sides) away.
constexpr double kMaxOffGridFraction = 1.0 / 3.0;

// The tags whose corners sit where the grid does not put their id — a tag misread as another id, or a stray quad
// decoded as a tag — dropped with the reason. Each tag is predicted from its neighbours: a homography from the board
// to the image fitted (RANSAC, so that one wrong neighbour does not decide) to the found corners of the other tags
// within two grid steps; local, so that lens distortion across the image does not matter. A tag with fewer than
// three such neighbours is kept: there is nothing to judge it by.
void DropTagsOffTheGrid(const AprilGridLayout& grid, AprilGridDetections* result) {
  std::vector<bool> off(result->tags.size(), false);
  for (size_t i = 0; i < result->tags.size(); ++i) {
    const TagDetection& tag = result->tags[i];
    const int col = tag.tag_index % grid.tag_cols, row = tag.tag_index / grid.tag_cols;
    std::vector<cv::Point2d> board, image;
    int neighbours = 0;
    for (size_t j = 0; j < result->tags.size(); ++j) {
      const TagDetection& other = result->tags[j];
      const int dc = other.tag_index % grid.tag_cols - col, dr = other.tag_index / grid.tag_cols - row;
      if (j == i || std::max(std::abs(dc), std::abs(dr)) > kNeighbourSteps) continue;
      ++neighbours;
      for (int k = 0; k < 4; ++k) {
        if (!other.corner_found[static_cast<size_t>(k)]) continue;
        board.push_back(TagCornerMm(grid, other.tag_index, k));
        image.emplace_back(other.corners_px[static_cast<size_t>(k)].x(), other.corners_px[static_cast<size_t>(k)].y());
      }
    }
    if (neighbours < kMinNeighbourTags || board.size() < 8) continue;
    double side_px = 0;
    for (size_t k = 0; k < 4; ++k) side_px += 0.25 * (tag.corners_px[(k + 1) % 4] - tag.corners_px[k]).norm();
    const cv::Mat h = cv::findHomography(board, image, cv::RANSAC, 0.1 * side_px);
    if (h.empty()) continue;
    std::vector<cv::Point2d> own_board, predicted;
    for (int k = 0; k < 4; ++k) own_board.push_back(TagCornerMm(grid, tag.tag_index, k));
    cv::perspectiveTransform(own_board, predicted, h);
    double worst_px = 0;
    for (size_t k = 0; k < 4; ++k) {
      if (!tag.corner_found[k]) continue;
      worst_px = std::max(worst_px, std::hypot(predicted[k].x - tag.corners_px[k].x(),
                                               predicted[k].y - tag.corners_px[k].y()));
    }
    if (worst_px > kMaxOffGridFraction * side_px) {
      off[i] = true;
      result->reasons.push_back(fmt::format("tag id {}: {:.0f} px from where its {} neighbours put it (a misread id?), "
                                            "left out",
                                            tag.tag_index + grid.first_tag_id, worst_px, neighbours));
    }
  }
  std::vector<TagDetection> kept;
  for (size_t i = 0; i < result->tags.size(); ++i) {
    if (off[i]) {
      ++result->rejected;
    } else {
      kept.push_back(result->tags[i]);
    }
  }
  result->tags = std::move(kept);
}

}  // namespace

void FinishAprilGridDetections(const AprilGridLayout& grid, AprilGridDetections* detections) {
  auto& result = *detections;
  std::sort(result.tags.begin(), result.tags.end(),
            [](const TagDetection& a, const TagDetection& b) { return a.tag_index < b.tag_index; });
  // A tag id seen twice is a misdetection of one of them: drop both rather than guess.
  std::vector<TagDetection> unique;
  for (size_t i = 0; i < result.tags.size(); ++i) {
    const bool dup = (i > 0 && result.tags[i - 1].tag_index == result.tags[i].tag_index) ||
                     (i + 1 < result.tags.size() && result.tags[i + 1].tag_index == result.tags[i].tag_index);
    if (dup) {
      ++result.rejected;
      result.reasons.push_back(
          fmt::format("tag id {}: seen twice, both left out", result.tags[i].tag_index + grid.first_tag_id));
    } else {
      unique.push_back(result.tags[i]);
    }
  }
  result.tags = std::move(unique);
  DropTagsOffTheGrid(grid, &result);
  result.message = fmt::format("{}/{} tags ({} rejected)", result.tags.size(), grid.NumTags(), result.rejected);
}

AprilGridDetections DetectAprilGrid(const cv::Mat& gray, const AprilGridLayout& grid, const DetectionOptions& options) {
  AprilGridDetections result;
  auto family = apriltag_raii::MakeTag36h11();
  apriltag_raii::Detector detector(apriltag_detector_create());
  if (!family || !detector) {
    result.message = "libapriltag: cannot create the detector";
    return result;
  }
  // Decoding up to 2 corrected bits lets the hamming filter see (and count) near-miss codes.
  apriltag_detector_add_family_bits(detector.get(), family.get(), std::max(2, options.max_hamming));
  detector->quad_decimate = static_cast<float>(options.quad_decimate);
  detector->quad_sigma = 0.0f;
  detector->nthreads = 1;
  detector->refine_edges = true;

  // libapriltag reads but does not write the pixels; it takes a non-const buffer, so hand it a private copy.
  cv::Mat copy = gray.clone();
  image_u8_t image{copy.cols, copy.rows, static_cast<int32_t>(copy.step[0]), copy.data};
  const apriltag_raii::Detections detections(apriltag_detector_detect(detector.get(), &image));
  if (!detections) {
    result.message = "libapriltag: detection failed";
    return result;
  }
  const int n = zarray_size(detections.get());
  for (int i = 0; i < n; ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(detections.get(), i, &det);
    const int index = det->id - grid.first_tag_id;
    std::string reason;
    if (index < 0 || index >= grid.NumTags()) {
      reason = fmt::format("not on this grid (ids {}..{})", grid.first_tag_id, grid.first_tag_id + grid.NumTags() - 1);
    } else if (det->hamming > options.max_hamming) {
      reason = fmt::format("{} corrected bit(s), more than --max-hamming {}", det->hamming, options.max_hamming);
    } else if (det->decision_margin < options.min_decision_margin) {
      reason = fmt::format("decision margin {:.1f} below {:.1f} (low contrast or blur)", det->decision_margin,
                           options.min_decision_margin);
    }
    if (!reason.empty()) {
      ++result.rejected;
      result.reasons.push_back(fmt::format("tag id {}: {}", det->id, reason));
      continue;
    }
    TagDetection tag;
    tag.tag_index = index;
    tag.decision_margin = det->decision_margin;
    tag.hamming = det->hamming;
    for (size_t k = 0; k < 4; ++k) {
      tag.corners_px[k] = Eigen::Vector2d(det->p[k][0], det->p[k][1]) +
                          Eigen::Vector2d::Constant(kAprilTagToOpenCvOffsetPx);
    }
    if (options.refinement != CornerRefinement::kNone) {
      int cells = 0;
      const auto bits = apriltag_raii::TagBitmap(family.get(), det->id, &cells);
      const auto refined = RefineTag(gray, tag.corners_px, grid, bits, cells);
      if (!refined) {
        ++result.rejected;
        result.reasons.push_back(fmt::format("tag id {}: its edges could not be fitted (occluded or at the image edge)",
                                             det->id));
        continue;
      }
      tag.corners_px = *refined;
    }
    result.tags.push_back(tag);
  }
  FinishAprilGridDetections(grid, &result);
  return result;
}

}  // namespace topocal::calib
