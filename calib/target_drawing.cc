#include "calib/target_drawing.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <opencv2/aruco.hpp>
#include <stdexcept>

#include "calib/apriltag_raii.h"
#include "imageio/image_file.h"
#include "plot/paper_svg.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

constexpr double kMmPerInch = 25.4;

}  // namespace

TargetPattern::TargetPattern(const TargetDescription& target) : target_(target), paper_(target.PaperExtent()) {
  if (const auto* g = std::get_if<AprilGridLayout>(&target_.layout)) {
    const auto family = apriltag_raii::MakeTag36h11();
    if (!family) throw std::runtime_error("libapriltag: cannot create the tag36h11 family");
    for (int i = 0; i < g->NumTags(); ++i) {
      int cells = 0;
      auto bits = apriltag_raii::TagBitmap(family.get(), g->first_tag_id + i, &cells);
      if (g->KalibrLayout()) {
        // Kalibr's tag: the same data bits inside a border one cell wider (libapriltag's 8 cells -> 10).
        const int wide = cells + 2;
        std::vector<uint8_t> kalibr(static_cast<size_t>(wide * wide), 1);
        for (int y = 1; y + 1 < cells; ++y) {
          for (int x = 1; x + 1 < cells; ++x) {
            kalibr[static_cast<size_t>((y + 1) * wide + x + 1)] = bits[static_cast<size_t>(y * cells + x)];
          }
        }
        bits = std::move(kalibr);
        cells = wide;
      }
      tag_cells_ = cells;
      tag_bits_.push_back(std::move(bits));
    }
  }
  if (const auto* c = std::get_if<CharucoLayout>(&target_.layout)) {
    // OpenCV's own marker bitmaps, one pixel per cell (the marker's 1-cell border included).
    const auto dictionary = cv::aruco::getPredefinedDictionary(*ArucoDictionaryId(c->dictionary));
    tag_cells_ = dictionary->markerSize + 2;
    for (int id = 0; id < c->NumMarkers(); ++id) {
      cv::Mat marker;
      cv::aruco::drawMarker(dictionary, id, tag_cells_, marker, 1);
      std::vector<uint8_t> bits(static_cast<size_t>(tag_cells_ * tag_cells_));
      for (int y = 0; y < tag_cells_; ++y) {
        for (int x = 0; x < tag_cells_; ++x) bits[static_cast<size_t>(y * tag_cells_ + x)] = marker.at<uint8_t>(y, x) < 128;
      }
      tag_bits_.push_back(std::move(bits));
    }
    // Markers fill the white squares ((x + y) odd) row-major from the top-left, as cv::aruco::CharucoBoard does.
    int next = 0;
    for (int y = 0; y < c->squares_y; ++y) {
      for (int x = 0; x < c->squares_x; ++x) marker_of_square_.push_back((x + y) % 2 == 1 ? next++ : -1);
    }
  }
}

bool TargetPattern::OnPaper(double x_mm, double y_mm) const noexcept {
  return x_mm >= paper_.min_x_mm && x_mm < paper_.max_x_mm && y_mm >= paper_.min_y_mm && y_mm < paper_.max_y_mm;
}

bool TargetPattern::IsBlack(double x_mm, double y_mm) const noexcept {
  if (const auto* b = std::get_if<CheckerboardLayout>(&target_.layout)) {
    // Square (i, j) spans [(i-1) s, i s): i = 0 .. cols, j = 0 .. rows; (0, 0) is black.
    const double fi = std::floor(x_mm / b->col_spacing_mm) + 1.0;
    const double fj = std::floor(y_mm / b->row_spacing_mm) + 1.0;
    if (fi < 0 || fj < 0 || fi > b->cols || fj > b->rows) return false;
    return (static_cast<long>(fi) + static_cast<long>(fj)) % 2 == 0;
  }
  if (const auto* c = std::get_if<CharucoLayout>(&target_.layout)) {
    const double fi = std::floor(x_mm / c->square_size_mm), fj = std::floor(y_mm / c->square_size_mm);
    if (fi < 0 || fj < 0 || fi >= c->squares_x || fj >= c->squares_y) return false;
    const int marker = marker_of_square_[static_cast<size_t>(static_cast<int>(fj) * c->squares_x + static_cast<int>(fi))];
    if (marker < 0) return true;  // black square
    const double u = (x_mm - fi * c->square_size_mm - c->MarginMm()) / c->marker_size_mm;
    const double v = (y_mm - fj * c->square_size_mm - c->MarginMm()) / c->marker_size_mm;
    if (u < 0 || v < 0 || u >= 1.0 || v >= 1.0) return false;  // white margin around the marker
    const int cx = std::min(tag_cells_ - 1, static_cast<int>(u * tag_cells_));
    const int cy = std::min(tag_cells_ - 1, static_cast<int>(v * tag_cells_));
    return tag_bits_[static_cast<size_t>(marker)][static_cast<size_t>(cy * tag_cells_ + cx)] != 0;
  }
  const auto& g = std::get<AprilGridLayout>(target_.layout);
  const double pitch = g.PitchMm();
  if (g.KalibrLayout()) {
    // Corner squares fill every gap crossing: x in [k p - gap, k p) for k = 0 .. tag_cols, likewise y.
    const double gap = g.GapMm();
    const double kx = std::floor((x_mm + gap) / pitch), ky = std::floor((y_mm + gap) / pitch);
    if (kx >= 0 && ky >= 0 && kx <= g.tag_cols && ky <= g.tag_rows && x_mm + gap - kx * pitch < gap &&
        y_mm + gap - ky * pitch < gap) {
      return true;
    }
  }
  const double fi = std::floor(x_mm / pitch), fj = std::floor(y_mm / pitch);
  if (fi < 0 || fj < 0 || fi >= g.tag_cols || fj >= g.tag_rows) return false;
  const double u = (x_mm - fi * pitch) / g.tag_size_mm, v = (y_mm - fj * pitch) / g.tag_size_mm;
  if (u >= 1.0 || v >= 1.0) return false;  // in the white gap
  const int cx = std::min(tag_cells_ - 1, static_cast<int>(u * tag_cells_));
  const int cy = std::min(tag_cells_ - 1, static_cast<int>(v * tag_cells_));
  // Rows are numbered from the bottom of the print (calib/target.h).
  const int tag = (g.tag_rows - 1 - static_cast<int>(fj)) * g.tag_cols + static_cast<int>(fi);
  const auto& bits = tag_bits_[static_cast<size_t>(tag)];
  return bits[static_cast<size_t>(cy * tag_cells_ + cx)] != 0;
}

std::string TargetSvg(const TargetDescription& target) {
  const TargetPattern pattern(target);
  const TargetExtent paper = target.PaperExtent();
  plot::PaperSvg svg("topocal target: " + target.Describe(), paper.WidthMm(), paper.HeightMm());
  // Target-plane mm to the sheet's top-left origin.
  auto rect = [&](double x_mm, double y_mm, double w_mm, double h_mm) {
    svg.BlackRect(x_mm - paper.min_x_mm, y_mm - paper.min_y_mm, w_mm, h_mm);
  };
  // A tag's or marker's cells of n x n, top-left at (x0, y0): runs of black cells become one rectangle (fewer
  // elements, no hairline seams between cells).
  auto bitmap = [&](const std::vector<uint8_t>& bits, int n, double x0, double y0, double cell_mm) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n;) {
        if (!bits[static_cast<size_t>(y * n + x)]) {
          ++x;
          continue;
        }
        int end = x;
        while (end < n && bits[static_cast<size_t>(y * n + end)]) ++end;
        rect(x0 + x * cell_mm, y0 + y * cell_mm, (end - x) * cell_mm, cell_mm);
        x = end;
      }
    }
  };
  if (const auto* b = std::get_if<CheckerboardLayout>(&target.layout)) {
    for (int j = 0; j <= b->rows; ++j) {
      for (int i = 0; i <= b->cols; ++i) {
        if ((i + j) % 2 == 0) {
          rect((i - 1) * b->col_spacing_mm, (j - 1) * b->row_spacing_mm, b->col_spacing_mm, b->row_spacing_mm);
        }
      }
    }
  } else if (const auto* c = std::get_if<CharucoLayout>(&target.layout)) {
    const int n = pattern.tag_cells();
    int marker = 0;
    for (int j = 0; j < c->squares_y; ++j) {
      for (int i = 0; i < c->squares_x; ++i) {
        if ((i + j) % 2 == 0) {
          rect(i * c->square_size_mm, j * c->square_size_mm, c->square_size_mm, c->square_size_mm);
          continue;
        }
        svg.Comment(fmt::format("marker {}", marker));
        bitmap(pattern.tag_bits()[static_cast<size_t>(marker++)], n, i * c->square_size_mm + c->MarginMm(),
               j * c->square_size_mm + c->MarginMm(), c->marker_size_mm / n);
      }
    }
  } else {
    const auto& g = std::get<AprilGridLayout>(target.layout);
    const int n = pattern.tag_cells();
    if (g.KalibrLayout()) {
      svg.Comment("corner squares (Kalibr)");
      for (int ky = 0; ky <= g.tag_rows; ++ky) {
        for (int kx = 0; kx <= g.tag_cols; ++kx) {
          rect(kx * g.PitchMm() - g.GapMm(), ky * g.PitchMm() - g.GapMm(), g.GapMm(), g.GapMm());
        }
      }
    }
    for (int t = 0; t < g.NumTags(); ++t) {
      const Eigen::Vector2d origin = g.TagOriginMm(t);
      svg.Comment(fmt::format("tag {}", g.first_tag_id + t));
      bitmap(pattern.tag_bits()[static_cast<size_t>(t)], n, origin.x(), origin.y(), g.tag_size_mm / n);
    }
  }
  return std::move(svg).Finish();
}

cv::Mat RasterizeTarget(const TargetDescription& target, double dpi, int max_side_px) {
  const TargetPattern pattern(target);
  const TargetExtent paper = target.PaperExtent();
  const double px_per_mm = dpi / kMmPerInch;
  const double width = std::round(paper.WidthMm() * px_per_mm), height = std::round(paper.HeightMm() * px_per_mm);
  if (!(width >= 1 && height >= 1 && width <= max_side_px && height <= max_side_px)) return {};
  cv::Mat image(static_cast<int>(height), static_cast<int>(width), CV_8UC1);
  for (int y = 0; y < image.rows; ++y) {
    auto* row = image.ptr<uint8_t>(y);
    const double y_mm = paper.min_y_mm + (y + 0.5) / px_per_mm;
    for (int x = 0; x < image.cols; ++x) {
      row[x] = pattern.IsBlack(paper.min_x_mm + (x + 0.5) / px_per_mm, y_mm) ? 0 : 255;
    }
  }
  return image;
}

void WriteTargetDrawing(const TargetDescription& target, const std::string& path, double dpi) {
  std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".svg") {
    util::WriteFileAtomic(path, TargetSvg(target));
    return;
  }
  if (ext != ".png") throw util::InputError(fmt::format("{}: output must end in .svg or .png", path));
  if (!std::isfinite(dpi) || dpi <= 0) throw util::InputError(fmt::format("--dpi: must be positive, got {}", dpi));
  const cv::Mat image = RasterizeTarget(target, dpi);
  if (image.empty()) {
    throw util::InputError(
        fmt::format("{}: {} at {} dpi is too large a raster (use SVG or a lower --dpi)", path, target.Describe(), dpi));
  }
  // PNG's pHYs chunk is not written by OpenCV; the physical size comes from the dpi the user prints at.
  imageio::WritePng(path, image);
}

}  // namespace topocal::calib
