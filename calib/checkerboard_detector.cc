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

std::optional<std::vector<Eigen::Vector2d>> DetectCheckerboardCorners(const cv::Mat& gray,
                                                                      const CheckerboardLayout& board,
                                                                      const DetectionOptions& options,
                                                                      std::string* why) {
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> found;
  bool ok = false;
  try {
    ok = cv::findChessboardCornersSB(gray, pattern, found, cv::CALIB_CB_NORMALIZE_IMAGE);
    if (!ok) {
      found.clear();
      ok = cv::findChessboardCorners(gray, pattern, found,
                                     cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    }
  } catch (const cv::Exception& e) {
    if (why) *why = fmt::format("OpenCV board detector failed: {}", e.err);
    return std::nullopt;
  }
  if (!ok || found.size() != static_cast<size_t>(board.cols * board.rows)) {
    if (why) *why = fmt::format("no {}x{} checkerboard found", board.cols, board.rows);
    return std::nullopt;
  }
  std::vector<Eigen::Vector2d> corners;
  corners.reserve(found.size());
  for (const auto& p : found) corners.emplace_back(p.x, p.y);
  Canonicalise(gray, board, corners);

  if (options.refinement == CornerRefinement::kOpenCvSubPix) {
    std::vector<cv::Point2f> points;
    for (const auto& p : corners) points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    cv::cornerSubPix(gray, points, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.001));
    for (size_t i = 0; i < points.size(); ++i) corners[i] = Eigen::Vector2d(points[i].x, points[i].y);
  } else if (options.refinement == CornerRefinement::kSaddle) {
    cv::Mat image;
    gray.convertTo(image, CV_32F);
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
        const auto refined = RefineSaddle(image, corners[i], fit);
        if (!refined) {
          if (why) *why = fmt::format("corner {} could not be refined (window leaves the image or no saddle)", i);
          return std::nullopt;
        }
        corners[i] = *refined;
      }
    }
  }
  return corners;
}

}  // namespace topocal::calib
