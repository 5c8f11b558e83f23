#include "calib/checkerboard_detector.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "calib/corner_refinement.h"

namespace topocal::calib {
namespace {

// Saddle window from the local corner spacing: a quarter of the nearest-neighbour distance keeps the weights of
// the board's outer border (one square away, where point symmetry ends) below exp(-8). Within that, wider windows
// average more noise but see more of the edges' bending by lens distortion: on the test renders (blur 1 px,
// k1 = -0.18) sigma 1.5 px gives 0.003-0.005 px RMS without noise and 0.014-0.019 px at 2 grey levels, 4 px gives
// 0.006-0.014 px and 0.011-0.018 px; 3 px is the compromise.
constexpr double kWindowFractionOfSpacing = 0.25;
constexpr double kMinWindowSigmaPx = 1.5;
constexpr double kMaxWindowSigmaPx = 3.0;
// Near the image edge a window down to this sigma is still tried before the corner is left out (with 2.1 px of
// window radius the six-coefficient fit still sees ~20 pixels).
constexpr double kMinEdgeWindowSigmaPx = 0.7;
// The board search runs on the pyramid level whose longer side is at most this (squares of a board that fills a
// tenth of the image stay >= ~10 px there, what the classic detector needs).
constexpr int kSearchMaxSidePx = 1280;

double MeanGrey(const cv::Mat& gray, const Eigen::Vector2d& p) {
  const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
  if (x < 1 || y < 1 || x + 1 >= gray.cols || y + 1 >= gray.rows) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) sum += gray.at<uint8_t>(y + dy, x + dx);
  }
  return sum / 9.0;
}

// Puts OpenCV's row-major corners into the target's orientation (see the header).
void Canonicalise(const cv::Mat& gray, const CheckerboardLayout& board, std::vector<Eigen::Vector2d>& c) {
  const int cols = board.cols, rows = board.rows;
  auto at = [&](int r, int col) -> Eigen::Vector2d& { return c[static_cast<size_t>(r * cols + col)]; };
  const Eigen::Vector2d vx = at(0, cols - 1) - at(0, 0), vy = at(rows - 1, 0) - at(0, 0);
  if (vx.x() * vy.y() - vx.y() * vy.x() < 0) {  // mirrored: reverse each row
    for (int r = 0; r < rows; ++r) std::reverse(c.begin() + r * cols, c.begin() + (r + 1) * cols);
  }
  bool rotate = false;
  if ((cols + rows) % 2 == 1) {
    // Squares around corner 0: the diagonal ones (outer (0,0) and inner (1,1)) are black on the target.
    const Eigen::Vector2d dx = 0.5 * (at(0, 1) - at(0, 0)), dy = 0.5 * (at(1, 0) - at(0, 0));
    const Eigen::Vector2d o = at(0, 0);
    const double diagonal = MeanGrey(gray, o - dx - dy) + MeanGrey(gray, o + dx + dy);
    const double off_diagonal = MeanGrey(gray, o + dx - dy) + MeanGrey(gray, o - dx + dy);
    rotate = diagonal > off_diagonal;  // NaN (sample outside the image) compares false: keep OpenCV's order
  } else {
    rotate = c.back().sum() < c.front().sum();
  }
  if (rotate) std::reverse(c.begin(), c.end());
}

}  // namespace

std::optional<CheckerboardCorners> DetectCheckerboardCorners(const cv::Mat& gray, const CheckerboardLayout& board,
                                                             const DetectionOptions& options, std::string* why) {
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> found;
  bool ok = false;
  constexpr int kClassicFlags = cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE;
  try {
    // The classic detector is 5-8x faster than the SB one (issue 11) and, refined by the saddle fit, gives the
    // same corners. Its cost grows with the pixel count while the corners' accuracy comes from the saddle fit at
    // full resolution, so large images are searched at a pyramid level (a 4000 x 3000 sensor at 1000 x 750). SB
    // (a different board search) only rescues the images where the classic one fails at full resolution.
    cv::Mat search = gray;
    int level = 0;
    while (std::max(search.cols, search.rows) > kSearchMaxSidePx) {
      cv::pyrDown(search, search);
      ++level;
    }
    ok = cv::findChessboardCorners(search, pattern, found, kClassicFlags);
    if (ok && level > 0) {
      // pyrDown's pixel i is the 5-tap Gaussian centred on input pixel 2 i: x_full = 2 x_half per level.
      const float factor = static_cast<float>(1 << level);
      for (auto& p : found) p *= factor;
    }
    if (!ok && level > 0) {
      found.clear();
      ok = cv::findChessboardCorners(gray, pattern, found, kClassicFlags);
    }
    if (!ok) {
      found.clear();
      ok = cv::findChessboardCornersSB(gray, pattern, found, cv::CALIB_CB_NORMALIZE_IMAGE);
    }
  } catch (const cv::Exception& e) {
    if (why) *why = fmt::format("OpenCV board detector failed: {}", e.err);
    return std::nullopt;
  }
  if (!ok || found.size() != static_cast<size_t>(board.cols * board.rows)) {
    if (why) {
      *why = fmt::format("no {}x{} checkerboard found", board.cols, board.rows);
      // The common mistake: squares counted instead of inner corners. Only tried once the board was not found.
      std::vector<cv::Point2f> smaller;
      if (board.cols > 2 && board.rows > 2 &&
          cv::findChessboardCorners(gray, cv::Size(board.cols - 1, board.rows - 1), smaller,
                                    cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) {
        *why += fmt::format(" (hint: the image shows a {}x{} board: targetCols/targetRows count INNER corners, one "
                            "fewer than the squares)",
                            board.cols - 1, board.rows - 1);
      }
    }
    return std::nullopt;
  }
  CheckerboardCorners result;
  result.corners_px.reserve(found.size());
  for (const auto& p : found) result.corners_px.emplace_back(p.x, p.y);
  result.found.assign(found.size(), true);
  auto& corners = result.corners_px;
  Canonicalise(gray, board, corners);

  if (options.refinement == CornerRefinement::kOpenCvSubPix) {
    std::vector<cv::Point2f> points;
    for (const auto& p : corners) points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    cv::cornerSubPix(gray, points, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.001));
    for (size_t i = 0; i < points.size(); ++i) corners[i] = Eigen::Vector2d(points[i].x, points[i].y);
  } else if (options.refinement == CornerRefinement::kSaddle) {
    // Only the board's neighbourhood is converted to float (a 4000 x 3000 image is 48 MB as float).
    double min_x = gray.cols, min_y = gray.rows, max_x = 0, max_y = 0;
    for (const auto& p : corners) {
      min_x = std::min(min_x, p.x());
      min_y = std::min(min_y, p.y());
      max_x = std::max(max_x, p.x());
      max_y = std::max(max_y, p.y());
    }
    constexpr int kRoiMarginPx = 16;  // >= SaddleWindowHalfWidthPx(kMaxWindowSigmaPx) + max_shift_px + 1
    const cv::Rect roi = cv::Rect(cv::Point(static_cast<int>(min_x) - kRoiMarginPx, static_cast<int>(min_y) - kRoiMarginPx),
                                  cv::Point(static_cast<int>(max_x) + kRoiMarginPx + 1,
                                            static_cast<int>(max_y) + kRoiMarginPx + 1)) &
                         cv::Rect(0, 0, gray.cols, gray.rows);
    cv::Mat image;
    gray(roi).convertTo(image, CV_32F);
    const Eigen::Vector2d offset(roi.x, roi.y);
    for (int r = 0; r < board.rows; ++r) {
      for (int col = 0; col < board.cols; ++col) {
        const size_t i = static_cast<size_t>(r * board.cols + col);
        SaddleFitOptions fit;
        if (options.saddle_window_sigma_px > 0) {
          fit.window_sigma_px = options.saddle_window_sigma_px;
        } else {
          double spacing = std::numeric_limits<double>::infinity();
          if (col > 0) spacing = std::min(spacing, (corners[i] - corners[i - 1]).norm());
          if (col + 1 < board.cols) spacing = std::min(spacing, (corners[i] - corners[i + 1]).norm());
          if (r > 0) spacing = std::min(spacing, (corners[i] - corners[i - static_cast<size_t>(board.cols)]).norm());
          if (r + 1 < board.rows) {
            spacing = std::min(spacing, (corners[i] - corners[i + static_cast<size_t>(board.cols)]).norm());
          }
          fit.window_sigma_px = std::clamp(kWindowFractionOfSpacing * spacing, kMinWindowSigmaPx, kMaxWindowSigmaPx);
        }
        // Near the image edge: the largest window that stays inside (one pixel spare for the corner's motion).
        const Eigen::Vector2d& p = corners[i];
        const double room_px = std::min({p.x(), p.y(), gray.cols - 1.0 - p.x(), gray.rows - 1.0 - p.y()}) - 1.0;
        if (SaddleWindowHalfWidthPx(fit.window_sigma_px) > room_px) {
          fit.window_sigma_px = SaddleSigmaForRoomPx(room_px);
        }
        std::optional<Eigen::Vector2d> refined;
        if (fit.window_sigma_px >= kMinEdgeWindowSigmaPx) refined = RefineSaddle(image, p - offset, fit);
        if (refined) {
          corners[i] = *refined + offset;
        } else {
          result.found[i] = false;
          result.reasons.push_back(fmt::format("corner {}: {}", i,
                                               fit.window_sigma_px < kMinEdgeWindowSigmaPx
                                                   ? "at the image edge, left out"
                                                   : "no saddle there (occluded or blurred), left out"));
        }
      }
    }
  }
  return result;
}

}  // namespace topocal::calib
