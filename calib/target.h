#pragma once
// A planar calibration target: its description file and the positions of its corners on the target plane.
//
// Description file: YAML with Kalibr's field names (lengths in metres in the file, millimetres in code).
//
//   checkerboard                              aprilgrid
//   ------------                              ---------
//   target_type: checkerboard                 target_type: aprilgrid
//   targetCols: 9        # inner corners, x   tagCols: 6             # tags along x
//   targetRows: 6        # inner corners, y   tagRows: 6             # tags along y
//   rowSpacingMeters: 0.025  # square, y      tagSize: 0.088         # black square edge, m
//   colSpacingMeters: 0.025  # square, x      tagSpacing: 0.3        # gap between tags / tagSize
//                                             tagFamily: tag36h11    # topocal: optional, only tag36h11
//                                             firstTagId: 0          # topocal: optional, default 0
//
// Parsing is strict: a missing, unknown, wrongly typed or non-positive key is a model::InputError
// "FILE: KEY: problem". A leading "%YAML:1.0" line is optional (plain Kalibr files are accepted).
//
// Target frame (mm): z = 0 is the printed plane, x to the right and y DOWN as the target is printed and seen from
// the front, z into the target (so a camera looking at the front with its x right / y down sees the target with
// identity rotation).
//
// Checkerboard (targetCols = 4, targetRows = 3 shown). Corner ids are row-major over the INNER corners; corner 0 is
// the origin; the square diagonally up-left of corner 0 is black (so for an odd cols + rows the 180-degree
// rotation is distinguishable and the detector reports ids in this orientation).
//
//        x -->
//     ##########          ##########          ##########
//     ##########          ##########          ##########
//     ##########          ##########          ##########
//   y           0---------1---------2---------3           corner id = r * targetCols + c
//   |           |##########         |##########           at (c * colSpacing, r * rowSpacing, 0) mm
//   v           |##########         |##########
//               4---------5---------6---------7
//     ##########|         |##########         |##########
//               8---------9--------10--------11
//   (one square of white quiet border surrounds the outer squares)
//
// AprilTag grid. The tag at column i, row j (row 0 at the top) has id firstTagId + j * tagCols + i; its black
// square spans [i * p, i * p + s] x [j * p, j * p + s] with s = tagSize, p = s * (1 + tagSpacing). The tag is
// printed in libapriltag's canonical orientation (apriltag_to_image, bitmap row 0 at the top, y down).
// Its four corners, numbered as libapriltag numbers them for an upright tag:
//
//        x -->
//   y    3 ------------ 2        corner id = 4 * (tag id - firstTagId) + k    (k = 0..3)
//   |    | ############ |        0 = (x0,     y0 + s)   bottom-left
//   v    | ##  tag   ## |        1 = (x0 + s, y0 + s)   bottom-right
//        | ############ |        2 = (x0 + s, y0)       top-right
//        0 ------------ 1        3 = (x0,     y0)       top-left
//
// Corner ids are relative to firstTagId so that ids stay small; CornerObservation::id uses the same ids.
// The paper margin around the grid is half a tag (>= 4 bit cells of white), without Kalibr's corner squares.
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <Eigen/Core>

namespace topocal::calib {

struct CheckerboardLayout {
  int cols = 0;               // inner corners along x (Kalibr targetCols)
  int rows = 0;               // inner corners along y (Kalibr targetRows)
  double col_spacing_mm = 0;  // square size along x (Kalibr colSpacingMeters)
  double row_spacing_mm = 0;  // square size along y (Kalibr rowSpacingMeters)
};

struct AprilGridLayout {
  int tag_cols = 0;
  int tag_rows = 0;
  double tag_size_mm = 0;         // edge of the black square (Kalibr tagSize)
  double tag_spacing_ratio = 0;   // gap between neighbouring tags / tag size (Kalibr tagSpacing)
  std::string family = "tag36h11";
  int first_tag_id = 0;

  double PitchMm() const noexcept { return tag_size_mm * (1.0 + tag_spacing_ratio); }
  int NumTags() const noexcept { return tag_cols * tag_rows; }
};

struct TargetExtent {
  double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
  double WidthMm() const noexcept { return max_x_mm - min_x_mm; }
  double HeightMm() const noexcept { return max_y_mm - min_y_mm; }
};

struct TargetDescription {
  std::variant<CheckerboardLayout, AprilGridLayout> layout;
  std::string source;  // the file it was read from (for messages)

  bool IsCheckerboard() const noexcept { return std::holds_alternative<CheckerboardLayout>(layout); }
  // All corner ids of the target, ascending.
  std::vector<int> CornerIds() const;
  // Position of a corner on the target plane (z = 0), mm; nullopt for an id that is not on this target.
  std::optional<Eigen::Vector3d> CornerMm(int id) const;
  // Bounding box of the printed pattern (black squares) and of the paper (pattern + white quiet border), mm.
  TargetExtent PatternExtent() const;
  TargetExtent PaperExtent() const;
  // One line, e.g. "checkerboard 9x6 inner corners, 25 x 25 mm squares".
  std::string Describe() const;
};

// Parses a target description (YAML text); `name` is used in error messages. Throws model::InputError.
TargetDescription ParseTargetDescription(std::string_view yaml_text, const std::string& name);
// Reads and parses a target description file. Throws model::InputError "PATH: KEY: problem".
TargetDescription LoadTargetDescription(const std::string& path);

}  // namespace topocal::calib
