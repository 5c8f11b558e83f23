#pragma once
// The printed appearance of a calibration target: an exact black/white pattern on the target plane (mm), and
// print-ready drawings of it at physical scale.
//
// The pattern is what calib/target.h draws: checkerboard squares inside a one-square white border; AprilTag grids
// as Kalibr prints them (tag36h11 data bits from libapriltag's bitmaps inside a 2-cell black border, black squares
// in the gap crossings) or, with tagBorderBits: 1, as plain libapriltag tags without corner squares; ChArUco boards
// as cv::aruco::CharucoBoard lays them out.
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "calib/target.h"

namespace topocal::calib {

class TargetPattern {
 public:
  explicit TargetPattern(const TargetDescription& target);

  // Reflectance at a point of the target plane: true = black ink. Points outside the paper are white here; the
  // caller decides what lies beyond the paper (PaperExtent()).
  bool IsBlack(double x_mm, double y_mm) const noexcept;
  bool OnPaper(double x_mm, double y_mm) const noexcept;
  const TargetDescription& target() const noexcept { return target_; }

  // Tag bitmaps: for each tag index (id - firstTagId), cells x cells values (row-major, y down), true = black; the
  // outermost ring (two rings for Kalibr's layout: 10 cells, else 8) is the black border. ChArUco: the markers by
  // id (OpenCV's bitmaps with their 1-cell border). Empty for checkerboards.
  int tag_cells() const noexcept { return tag_cells_; }
  const std::vector<std::vector<uint8_t>>& tag_bits() const noexcept { return tag_bits_; }

 private:
  TargetDescription target_;
  TargetExtent paper_;
  int tag_cells_ = 0;
  std::vector<std::vector<uint8_t>> tag_bits_;
  std::vector<int> marker_of_square_;  // ChArUco: marker index of each square (row-major), -1 for black squares
};

// SVG in millimetre units (width/height in mm, viewBox in mm), paper included, origin at the paper's top-left.
std::string TargetSvg(const TargetDescription& target);
// 8-bit raster of the paper at `dpi` (0 black, 255 white). Each pixel takes the ink at its centre.
// Returns an empty Mat when the raster would exceed max_side_px on a side.
cv::Mat RasterizeTarget(const TargetDescription& target, double dpi, int max_side_px = 30000);
// Writes .svg or .png (by extension, case-insensitive) atomically. Throws util::InputError on a bad path,
// extension or dpi.
void WriteTargetDrawing(const TargetDescription& target, const std::string& path, double dpi);

}  // namespace topocal::calib
