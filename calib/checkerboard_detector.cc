#include "calib/checkerboard_detector.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

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

// The common mistake: a description one row or column off what the image shows (squares counted instead of inner
// corners, or a miscount). Only tried once the board was not found, at the search level (each try is one bounded
// classic search, FAST_CHECK first): " (hint: ...)" when the image shows a board of N +- 1 corners, else "".
std::string BoardSizeHint(const cv::Mat& search, const CheckerboardLayout& board, int flags) {
  const int c = board.cols, r = board.rows;
  const std::pair<int, int> candidates[] = {{c - 1, r - 1}, {c - 1, r}, {c, r - 1}, {c + 1, r + 1},
                                            {c + 1, r},     {c, r + 1}, {c - 1, r + 1}, {c + 1, r - 1}};
  for (const auto& [cols, rows] : candidates) {
    if (cols < 2 || rows < 2) continue;
    std::vector<cv::Point2f> corners;
    bool seen = false;
    try {
      seen = cv::findChessboardCorners(search, cv::Size(cols, rows), corners, flags);
    } catch (const cv::Exception&) {
      seen = false;
    }
    if (seen) {
      return fmt::format(" (hint: the image shows a {}x{} board of inner corners where the description says {}x{}: "
                         "targetCols/targetRows count INNER corners, one fewer than the squares along a side)",
                         cols, rows, c, r);
    }
  }
  return "";
}

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

// ---- A board cut by the frame --------------------------------------------------------------------------------
// cv::findChessboardCornersSB with CALIB_CB_LARGER returns the largest grid of corners it can see, of any size from
// kMinPartialGrid up. Which board corners those are is decided here by elimination: a placement of the grid on the
// board (one of the 8 symmetries of the lattice, then an offset) survives when
//  - it fits on the board;
//  - it keeps the board's handedness (x then y turn clockwise in the image, as for whole boards);
//  - the squares it calls black are darker than those it calls white (the board's black outer corner squares);
//  - every board corner it leaves unseen extrapolates (the grid's homography) beyond the image, or to within one
//    square of its border where no detector finds corners: an unseen corner well inside the image contradicts it.
// Placements that differ by a symmetry of the board itself (a 180-degree turn when cols + rows is even, a quarter
// turn of a square board with the colours kept) label the same physical board and count once. Exactly one
// survivor: the identities are unambiguous and the grid is used; otherwise the view is refused with the count.
// Written here because OpenCV's detectors return a grid without its place on the board (only ChArUco and AprilGrid
// markers carry identities).
constexpr int kMinPartialGrid = 3;

struct Placement {
  bool swap = false, flip_a = false, flip_b = false;  // grid (row i, col j) -> board (c, r)
  int offset_c = 0, offset_r = 0;
  int grid_rows = 0, grid_cols = 0;
  Eigen::Vector2i BoardOf(int i, int j) const {
    const int u = swap ? i : j, v = swap ? j : i;  // u runs along the board's columns, v along its rows
    const int nu = swap ? grid_rows : grid_cols, nv = swap ? grid_cols : grid_rows;
    return {offset_c + (flip_a ? nu - 1 - u : u), offset_r + (flip_b ? nv - 1 - v : v)};
  }
  // The grid coordinates (col j, row i) of a board corner, possibly outside the grid.
  Eigen::Vector2d GridOf(int c, int r) const {
    const int nu = swap ? grid_rows : grid_cols, nv = swap ? grid_cols : grid_rows;
    int u = c - offset_c, v = r - offset_r;
    if (flip_a) u = nu - 1 - u;
    if (flip_b) v = nv - 1 - v;
    return swap ? Eigen::Vector2d(v, u) : Eigen::Vector2d(u, v);
  }
};

// A board symmetry as a map of corner ids, or nothing when it does not map the board (and its colours) onto itself.
std::vector<std::vector<int>> BoardSymmetries(const CheckerboardLayout& board) {
  const int cols = board.cols, rows = board.rows;
  std::vector<std::vector<int>> out;
  const auto add = [&](auto map, bool colours_kept) {
    if (!colours_kept) return;
    std::vector<int> ids(static_cast<size_t>(cols * rows));
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const Eigen::Vector2i m = map(c, r);
        ids[static_cast<size_t>(r * cols + c)] = m.y() * cols + m.x();
      }
    }
    out.push_back(std::move(ids));
  };
  // Square S(a, b) spans corners a..a+1, b..b+1 and is black when a + b is even (S(-1, -1), before corner 0, is).
  add([&](int c, int r) { return Eigen::Vector2i(cols - 1 - c, rows - 1 - r); }, (cols + rows) % 2 == 0);
  if (cols == rows) {
    add([&](int c, int r) { return Eigen::Vector2i(r, cols - 1 - c); }, cols % 2 == 0);
    add([&](int c, int r) { return Eigen::Vector2i(cols - 1 - r, c); }, cols % 2 == 0);
  }
  return out;
}

// The partial grid SB returned: its corners row-major over rows x cols.
struct PartialGrid {
  const std::vector<Eigen::Vector2d>& px;
  int rows = 0, cols = 0;
  const Eigen::Vector2d& at(int i, int j) const { return px[static_cast<size_t>(i * cols + j)]; }
};

// The grid's homography (grid col, row) -> image, to extrapolate the corners it does not show (empty: none).
cv::Mat GridHomography(const PartialGrid& grid) {
  std::vector<cv::Point2d> from, to;
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      from.emplace_back(j, i);
      to.emplace_back(grid.at(i, j).x(), grid.at(i, j).y());
    }
  }
  return cv::findHomography(from, to, 0);
}

std::optional<Eigen::Vector2d> Project(const cv::Mat& h, const Eigen::Vector2d& g) {
  const double w = h.at<double>(2, 0) * g.x() + h.at<double>(2, 1) * g.y() + h.at<double>(2, 2);
  if (!(w > 1e-9)) return std::nullopt;  // behind the camera: not in the image either
  return Eigen::Vector2d((h.at<double>(0, 0) * g.x() + h.at<double>(0, 1) * g.y() + h.at<double>(0, 2)) / w,
                         (h.at<double>(1, 0) * g.x() + h.at<double>(1, 1) * g.y() + h.at<double>(1, 2)) / w);
}

// Grey at the middle of each grid cell, and the cell's parity on the grid.
struct GridCell {
  int i, j;
  double grey;
};

std::vector<GridCell> CellGreys(const cv::Mat& gray, const PartialGrid& grid) {
  std::vector<GridCell> cells;
  for (int i = 0; i + 1 < grid.rows; ++i) {
    for (int j = 0; j + 1 < grid.cols; ++j) {
      const double g = MeanGrey(gray, 0.25 * (grid.at(i, j) + grid.at(i, j + 1) + grid.at(i + 1, j) + grid.at(i + 1, j + 1)));
      if (std::isfinite(g)) cells.push_back({i, j, g});
    }
  }
  return cells;
}

// Handedness: the board's +x and +y directions turn clockwise in the image (y down).
bool KeepsHandedness(const Placement& p, const PartialGrid& grid) {
  const Eigen::Vector2d g0 = p.GridOf(p.offset_c, p.offset_r);
  const Eigen::Vector2d gx = p.GridOf(p.offset_c + 1, p.offset_r) - g0, gy = p.GridOf(p.offset_c, p.offset_r + 1) - g0;
  const auto i0 = static_cast<int>(g0.y()), j0 = static_cast<int>(g0.x());
  const Eigen::Vector2d origin = grid.at(i0, j0);
  const Eigen::Vector2d vx = grid.at(i0 + static_cast<int>(gx.y()), j0 + static_cast<int>(gx.x())) - origin;
  const Eigen::Vector2d vy = grid.at(i0 + static_cast<int>(gy.y()), j0 + static_cast<int>(gy.x())) - origin;
  return !(vx.x() * vy.y() - vx.y() * vy.x() <= 0);
}

// Colours: the square after board corner (c, r) is black when c + r is even.
bool BlackIsDarker(const Placement& p, const std::vector<GridCell>& cells) {
  double black = 0, white = 0;
  int nb = 0, nw = 0;
  for (const GridCell& cell : cells) {
    const Eigen::Vector2i a = p.BoardOf(cell.i, cell.j), b = p.BoardOf(cell.i + 1, cell.j + 1);
    if ((std::min(a.x(), b.x()) + std::min(a.y(), b.y())) % 2 == 0) {
      black += cell.grey;
      ++nb;
    } else {
      white += cell.grey;
      ++nw;
    }
  }
  return !(nb == 0 || nw == 0 || !(black / nb < white / nw));
}

// The frame: every unseen board corner lies beyond the image or within a square of its border.
bool UnseenOutOfView(const cv::Mat& gray, const CheckerboardLayout& board, const PartialGrid& grid, const cv::Mat& h,
                     const Placement& p) {
  bool consistent = true;
  for (int r = 0; r < board.rows && consistent; ++r) {
    for (int c = 0; c < board.cols && consistent; ++c) {
      const Eigen::Vector2d g = p.GridOf(c, r);
      if (g.x() >= 0 && g.x() < grid.cols && g.y() >= 0 && g.y() < grid.rows) continue;
      const auto q = Project(h, g);
      if (!q) continue;
      const auto q1 = Project(h, g + Eigen::Vector2d(1, 0)), q2 = Project(h, g + Eigen::Vector2d(0, 1));
      double margin = 0;
      if (q1) margin = std::max(margin, (*q1 - *q).norm());
      if (q2) margin = std::max(margin, (*q2 - *q).norm());
      const bool inside = q->x() > margin && q->y() > margin && q->x() < gray.cols - 1 - margin &&
                          q->y() < gray.rows - 1 - margin;
      if (inside) consistent = false;
    }
  }
  return consistent;
}

// The board id of each grid corner under the placement.
std::vector<int> PlacementIds(const Placement& p, const CheckerboardLayout& board, const PartialGrid& grid) {
  std::vector<int> ids(grid.px.size(), -1);
  for (int i = 0; i < grid.rows; ++i) {
    for (int j = 0; j < grid.cols; ++j) {
      const Eigen::Vector2i b = p.BoardOf(i, j);
      ids[static_cast<size_t>(i * grid.cols + j)] = b.y() * board.cols + b.x();
    }
  }
  return ids;
}

// The least of the id maps the board's symmetries make of `ids`: one representative per physical placement.
std::vector<int> CanonicalIds(const std::vector<int>& ids, const std::vector<std::vector<int>>& symmetries) {
  std::vector<int> canonical = ids;
  for (const auto& s : symmetries) {
    std::vector<int> mapped(ids.size());
    for (size_t k = 0; k < ids.size(); ++k) mapped[k] = s[static_cast<size_t>(ids[k])];
    canonical = std::min(canonical, mapped);
  }
  return canonical;
}

std::string PlacementFailure(const CheckerboardLayout& board, const PartialGrid& grid, size_t placements) {
  return placements == 0
             ? fmt::format("partial board ({}x{} corners seen): no placement on the {}x{} board agrees with the "
                           "frame, the square colours and the board's handedness",
                           grid.cols, grid.rows, board.cols, board.rows)
             : fmt::format("partial board ({}x{} corners seen): {} placements on the {}x{} board fit, the "
                           "identities are ambiguous (a ChArUco board or an AprilGrid identifies every corner)",
                           grid.cols, grid.rows, placements, board.cols, board.rows);
}

// The ids of a partial grid on the board (-1: none), or nullopt with the reason.
std::optional<std::vector<int>> PlacePartialGrid(const cv::Mat& gray, const CheckerboardLayout& board,
                                                 const std::vector<Eigen::Vector2d>& grid_px, int grid_rows,
                                                 int grid_cols, std::string* why) {
  const PartialGrid grid{grid_px, grid_rows, grid_cols};
  const cv::Mat h = GridHomography(grid);
  if (h.empty()) {
    if (why) *why = "partial board: the corners found do not form a perspective grid";
    return std::nullopt;
  }
  const std::vector<GridCell> cells = CellGreys(gray, grid);
  const auto symmetries = BoardSymmetries(board);
  std::vector<std::vector<int>> classes;  // canonical id maps of the survivors
  std::vector<int> chosen;
  for (int t = 0; t < 8; ++t) {
    Placement p;
    p.swap = t & 1;
    p.flip_a = t & 2;
    p.flip_b = t & 4;
    p.grid_rows = grid_rows;
    p.grid_cols = grid_cols;
    const int nu = p.swap ? grid_rows : grid_cols, nv = p.swap ? grid_cols : grid_rows;
    for (p.offset_r = 0; p.offset_r + nv <= board.rows; ++p.offset_r) {
      for (p.offset_c = 0; p.offset_c + nu <= board.cols; ++p.offset_c) {
        if (!KeepsHandedness(p, grid) || !BlackIsDarker(p, cells) || !UnseenOutOfView(gray, board, grid, h, p)) continue;
        const std::vector<int> ids = PlacementIds(p, board, grid);
        const std::vector<int> canonical = CanonicalIds(ids, symmetries);
        if (std::find(classes.begin(), classes.end(), canonical) == classes.end()) {
          classes.push_back(canonical);
          if (classes.size() == 1) chosen = ids;
        }
      }
    }
  }
  if (classes.size() != 1) {
    if (why) *why = PlacementFailure(board, grid, classes.size());
    return std::nullopt;
  }
  return chosen;
}

// SB's grid stops about a square short of the frame; the board corners between it and the frame are found by
// stepping out from the grid: each is predicted from its two neighbours inward (2 p1 - p2, one square of
// extrapolation) and kept where a saddle fit converges within a quarter square of the prediction. Its identity
// is the placement's, so only its visibility is in question.
void ExtendToTheFrame(const cv::Mat& gray, const CheckerboardLayout& board, CheckerboardCorners& result) {
  constexpr int kMaxSteps = 3;
  const int cols = board.cols, rows = board.rows;
  for (int step = 0; step < kMaxSteps; ++step) {
    std::vector<std::pair<size_t, Eigen::Vector2d>> added;
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const size_t id = static_cast<size_t>(r * cols + c);
        if (result.found[id]) continue;
        for (const auto& [dc, dr] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
          const int c1 = c - dc, r1 = r - dr, c2 = c - 2 * dc, r2 = r - 2 * dr;
          if (c2 < 0 || c2 >= cols || r2 < 0 || r2 >= rows) continue;
          const size_t id1 = static_cast<size_t>(r1 * cols + c1), id2 = static_cast<size_t>(r2 * cols + c2);
          if (!result.found[id1] || !result.found[id2]) continue;
          const Eigen::Vector2d predicted = 2 * result.corners_px[id1] - result.corners_px[id2];
          const double spacing = (result.corners_px[id1] - result.corners_px[id2]).norm();
          const double room_px = std::min({predicted.x(), predicted.y(), gray.cols - 1.0 - predicted.x(),
                                           gray.rows - 1.0 - predicted.y()}) - 1.0;
          SaddleFitOptions fit;
          fit.window_sigma_px = std::clamp(kWindowFractionOfSpacing * spacing, kMinWindowSigmaPx, kMaxWindowSigmaPx);
          if (SaddleWindowHalfWidthPx(fit.window_sigma_px) > room_px) fit.window_sigma_px = SaddleSigmaForRoomPx(room_px);
          if (!(fit.window_sigma_px >= kMinEdgeWindowSigmaPx)) break;
          fit.max_shift_px = 0.25 * spacing;
          if (const auto refined = RefineSaddle(gray, predicted, fit)) added.emplace_back(id, *refined);
          break;
        }
      }
    }
    if (added.empty()) return;
    for (const auto& [id, px] : added) {
      result.corners_px[id] = px;
      result.found[id] = true;
      --result.beyond_frame;
    }
  }
}

// CALIB_CB_FAST_CHECK (OpenCV's quick test for chessboard-like black and white quads, ~0.4 s on a 1000 x 750
// noise frame) lets a frame without a board skip the classic search, which took 29 s on such a frame and 48 s
// for an absurd 200 x 150 board. A board the quick test misses is still found by SB below, which does
// not use it.
constexpr int kClassicFlags = cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK;

struct ClassicSearch {
  cv::Mat search;  // the pyramid level searched
  std::vector<cv::Point2f> found;
  bool ok = false;
};

// The classic detector is 5-8x faster than the SB one and, refined by the saddle fit, gives the same corners. Its
// cost grows with the pixel count while the corners' accuracy comes from the saddle fit at full resolution, so
// large images are searched at a pyramid level (a 4000 x 3000 sensor at 1000 x 750). SB (a different board
// search) only rescues the images where the classic one fails at full resolution.
// nullopt (with `why`) when OpenCV throws.
std::optional<ClassicSearch> SearchClassic(const cv::Mat& gray, const cv::Size& pattern, std::string* why) {
  ClassicSearch s;
  s.search = gray;
  try {
    int level = 0;
    while (std::max(s.search.cols, s.search.rows) > kSearchMaxSidePx) {
      cv::pyrDown(s.search, s.search);
      ++level;
    }
    s.ok = cv::findChessboardCorners(s.search, pattern, s.found, kClassicFlags);
    if (s.ok && level > 0) {
      // pyrDown's pixel i is the 5-tap Gaussian centred on input pixel 2 i: x_full = 2 x_half per level.
      const float factor = static_cast<float>(1 << level);
      for (auto& p : s.found) p *= factor;
    }
    if (!s.ok && level > 0) {
      s.found.clear();
      s.ok = cv::findChessboardCorners(gray, pattern, s.found, kClassicFlags);
    }
  } catch (const cv::Exception& e) {
    if (why) *why = fmt::format("OpenCV board detector failed: {}", e.err);
    return std::nullopt;
  }
  return s;
}

// SB's largest grid of corners. meta is (grid rows) x (grid cols), the corners row-major over it.
struct LargestGrid {
  std::vector<cv::Point2f> grid;
  cv::Mat meta;
  bool ok = false;
};

LargestGrid SearchLargestGrid(const cv::Mat& gray) {
  LargestGrid g;
  try {
    g.ok = cv::findChessboardCornersSB(gray, cv::Size(kMinPartialGrid, kMinPartialGrid), g.grid,
                                       cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_LARGER, g.meta);
  } catch (const cv::Exception&) {
    g.ok = false;
  }
  g.ok = g.ok && g.meta.rows * g.meta.cols == static_cast<int>(g.grid.size()) && g.meta.rows >= kMinPartialGrid &&
         g.meta.cols >= kMinPartialGrid;
  return g;
}

// The whole board from SB's grid into `found` (row-major over the board's columns), or false when the grid is not
// the whole board (`found` untouched).
bool WholeBoardOfGrid(const LargestGrid& g, const CheckerboardLayout& board, std::vector<cv::Point2f>& found) {
  if (g.ok && g.meta.rows == board.rows && g.meta.cols == board.cols) {
    found = g.grid;  // already row-major over the board's columns
    return true;
  }
  if (g.ok && g.meta.rows == board.cols && g.meta.cols == board.rows) {
    // Transposed: put it row-major over the board's columns (a mirror image, which Canonicalise undoes).
    found.clear();
    for (int r = 0; r < board.rows; ++r) {
      for (int c = 0; c < board.cols; ++c) found.push_back(g.grid[static_cast<size_t>(c * g.meta.cols + r)]);
    }
    return true;
  }
  return false;
}

// Not the whole board: the part of it that is in the image, when its place on the board is unambiguous. Fills
// `result` (left empty otherwise, with the reason in `partial_why`).
void PlacePartialBoard(const cv::Mat& gray, const CheckerboardLayout& board, const LargestGrid& g,
                       CheckerboardCorners& result, std::string& partial_why) {
  const cv::Mat& meta = g.meta;
  const int fits = (meta.cols <= board.cols && meta.rows <= board.rows) || (meta.rows <= board.cols && meta.cols <= board.rows);
  if (!fits) {
    partial_why = fmt::format("the image shows a {}x{} grid of corners, larger than the {}x{} board: check "
                              "targetCols/targetRows (inner corners)",
                              std::max(meta.cols, meta.rows), std::min(meta.cols, meta.rows), board.cols, board.rows);
    return;
  }
  std::vector<Eigen::Vector2d> grid_px;
  for (const auto& p : g.grid) grid_px.emplace_back(p.x, p.y);
  if (const auto ids = PlacePartialGrid(gray, board, grid_px, meta.rows, meta.cols, &partial_why)) {
    result.corners_px.assign(static_cast<size_t>(board.cols * board.rows), Eigen::Vector2d::Zero());
    result.found.assign(result.corners_px.size(), false);
    for (size_t k = 0; k < ids->size(); ++k) {
      result.corners_px[static_cast<size_t>((*ids)[k])] = grid_px[k];
      result.found[static_cast<size_t>((*ids)[k])] = true;
    }
    result.beyond_frame = board.cols * board.rows - static_cast<int>(ids->size());
    ExtendToTheFrame(gray, board, result);
  }
}

void RefineSubPix(const cv::Mat& gray, CheckerboardCorners& result) {
  auto& corners = result.corners_px;
  std::vector<cv::Point2f> points;
  std::vector<size_t> index;
  for (size_t i = 0; i < corners.size(); ++i) {
    if (!result.found[i]) continue;
    points.emplace_back(static_cast<float>(corners[i].x()), static_cast<float>(corners[i].y()));
    index.push_back(i);
  }
  cv::cornerSubPix(gray, points, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.001));
  for (size_t k = 0; k < points.size(); ++k) corners[index[k]] = Eigen::Vector2d(points[k].x, points[k].y);
}

// Only the board's neighbourhood is converted to float (a 4000 x 3000 image is 48 MB as float).
cv::Rect BoardRoi(const cv::Mat& gray, const CheckerboardCorners& result) {
  const auto& corners = result.corners_px;
  double min_x = gray.cols, min_y = gray.rows, max_x = 0, max_y = 0;
  for (size_t i = 0; i < corners.size(); ++i) {
    if (!result.found[i]) continue;
    const Eigen::Vector2d& p = corners[i];
    min_x = std::min(min_x, p.x());
    min_y = std::min(min_y, p.y());
    max_x = std::max(max_x, p.x());
    max_y = std::max(max_y, p.y());
  }
  constexpr int kRoiMarginPx = 16;  // >= SaddleWindowHalfWidthPx(kMaxWindowSigmaPx) + max_shift_px + 1
  return cv::Rect(cv::Point(static_cast<int>(min_x) - kRoiMarginPx, static_cast<int>(min_y) - kRoiMarginPx),
                  cv::Point(static_cast<int>(max_x) + kRoiMarginPx + 1, static_cast<int>(max_y) + kRoiMarginPx + 1)) &
         cv::Rect(0, 0, gray.cols, gray.rows);
}

// The saddle window of corner i (row r, column col): the option's, or from the distance to its nearest found
// neighbour; near the image edge the largest window that stays inside (one pixel spare for the corner's motion).
double SaddleWindowSigma(const cv::Mat& gray, const CheckerboardLayout& board, const DetectionOptions& options,
                         const CheckerboardCorners& result, int r, int col) {
  const auto& corners = result.corners_px;
  const size_t i = static_cast<size_t>(r * board.cols + col);
  double sigma = 0;
  if (options.saddle_window_sigma_px > 0) {
    sigma = options.saddle_window_sigma_px;
  } else {
    double spacing = std::numeric_limits<double>::infinity();
    const auto neighbour = [&](bool exists, size_t j) {
      if (exists && result.found[j]) spacing = std::min(spacing, (corners[i] - corners[j]).norm());
    };
    neighbour(col > 0, i - 1);
    neighbour(col + 1 < board.cols, i + 1);
    neighbour(r > 0, i - static_cast<size_t>(board.cols));
    neighbour(r + 1 < board.rows, i + static_cast<size_t>(board.cols));
    sigma = std::clamp(kWindowFractionOfSpacing * spacing, kMinWindowSigmaPx, kMaxWindowSigmaPx);
  }
  const Eigen::Vector2d& p = corners[i];
  const double room_px = std::min({p.x(), p.y(), gray.cols - 1.0 - p.x(), gray.rows - 1.0 - p.y()}) - 1.0;
  if (SaddleWindowHalfWidthPx(sigma) > room_px) {
    sigma = SaddleSigmaForRoomPx(room_px);
  }
  return sigma;
}

void RefineSaddles(const cv::Mat& gray, const CheckerboardLayout& board, const DetectionOptions& options,
                   CheckerboardCorners& result) {
  auto& corners = result.corners_px;
  const cv::Rect roi = BoardRoi(gray, result);
  cv::Mat image;
  gray(roi).convertTo(image, CV_32F);
  const Eigen::Vector2d offset(roi.x, roi.y);
  for (int r = 0; r < board.rows; ++r) {
    for (int col = 0; col < board.cols; ++col) {
      const size_t i = static_cast<size_t>(r * board.cols + col);
      if (!result.found[i]) continue;  // beyond the frame (a partial board)
      SaddleFitOptions fit;
      fit.window_sigma_px = SaddleWindowSigma(gray, board, options, result, r, col);
      const Eigen::Vector2d& p = corners[i];
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

}  // namespace

std::optional<CheckerboardCorners> DetectCheckerboardCorners(const cv::Mat& gray, const CheckerboardLayout& board,
                                                             const DetectionOptions& options, std::string* why) {
  const cv::Size pattern(board.cols, board.rows);
  auto classic = SearchClassic(gray, pattern, why);
  if (!classic) return std::nullopt;
  std::vector<cv::Point2f>& found = classic->found;
  bool ok = classic->ok;
  // Where the classic detector fails, SB searches once for the largest grid of corners of any size (CALIB_CB_LARGER):
  // the whole board, or the part of it in the image.
  LargestGrid sb;
  if (!ok) {
    sb = SearchLargestGrid(gray);
    ok = WholeBoardOfGrid(sb, board, found);
  }
  CheckerboardCorners result;
  if (ok && found.size() == static_cast<size_t>(board.cols * board.rows)) {
    result.corners_px.reserve(found.size());
    for (const auto& p : found) result.corners_px.emplace_back(p.x, p.y);
    result.found.assign(found.size(), true);
    Canonicalise(gray, board, result.corners_px);
  } else {
    std::string partial_why;
    if (sb.ok) PlacePartialBoard(gray, board, sb, result, partial_why);
    if (result.corners_px.empty()) {
      if (why) {
        *why = fmt::format("no {}x{} checkerboard found", board.cols, board.rows);
        if (!partial_why.empty()) *why += " (" + partial_why + ")";
        *why += BoardSizeHint(classic->search, board, kClassicFlags);
      }
      return std::nullopt;
    }
  }

  if (options.refinement == CornerRefinement::kOpenCvSubPix) {
    RefineSubPix(gray, result);
  } else if (options.refinement == CornerRefinement::kSaddle) {
    RefineSaddles(gray, board, options, result);
  }
  return result;
}

}  // namespace topocal::calib
