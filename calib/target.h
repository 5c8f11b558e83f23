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
//                                             tagBorderBits: 2       # topocal: optional, 2 (Kalibr) or 1
//
// Parsing is strict: a missing, unknown, wrongly typed or non-positive key is a util::InputError
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
// AprilTag grid, as Kalibr prints it (kalibr_create_target_pdf). The tag at column i, row j -- row 0 at the BOTTOM
// of the print, rows counted upwards, as Kalibr numbers them -- has id firstTagId + j * tagCols + i; its black square
// spans [i * p, i * p + s] x [(tagRows - 1 - j) * p, (tagRows - 1 - j) * p + s] (y down) with s = tagSize,
// p = s * (1 + tagSpacing). Tags are printed in libapriltag's canonical orientation (apriltag_to_image, bitmap row 0
// at the top, y down: the real Kalibr photos in data/ decode so).
//
//   tagBorderBits: 2 (Kalibr, the default)         tagBorderBits: 1 (topocal option: libapriltag's own tags)
//   the 6 x 6 data bits inside a 2-cell black      the 6 x 6 data bits inside a 1-cell black border (8 cells
//   border (10 cells across s), plus a black       across s), no corner squares
//   square of side g = tagSpacing * s in every
//   gap crossing (Kalibr's "symmCorners"):
//
//        x -->                                  so each tag corner is an X-junction:
//   y    ##   3 ------------ 2   ##                    gap   | corner square
//   |         | ############ |                   --------+--------   black tag opposite black square,
//   v         | ##  tag   ## |                     tag   |  gap      white gap opposite white gap
//             | ############ |
//        ##   0 ------------ 1   ##   corner id = 4 * (tag id - firstTagId) + k    (k = 0..3)
//                                     0 = (x0, y0 + s) bottom-left   1 = (x0 + s, y0 + s) bottom-right
//                                     2 = (x0 + s, y0) top-right     3 = (x0, y0) top-left
// (libapriltag's p[k] numbering for an upright tag). Corner ids are relative to firstTagId so that ids stay small;
// CornerObservation::id uses the same ids. The paper margin is half a tag of white beyond the pattern.
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
  int border_bits = 2;            // black border of a tag in bit cells: 2 = Kalibr (with corner squares), 1 = plain

  bool KalibrLayout() const noexcept { return border_bits == 2; }
  double GapMm() const noexcept { return tag_size_mm * tag_spacing_ratio; }
  // Top-left corner (x0, y0) of the black square of tag index t (= tag id - firstTagId), mm.
  Eigen::Vector2d TagOriginMm(int t) const noexcept {
    return {(t % tag_cols) * PitchMm(), (tag_rows - 1 - t / tag_cols) * PitchMm()};
  }

  double PitchMm() const noexcept { return tag_size_mm * (1.0 + tag_spacing_ratio); }
  int NumTags() const noexcept { return tag_cols * tag_rows; }
};

// ChArUco board (topocal's keys, OpenCV 4.6 contrib aruco's layout, y down as drawn by cv::aruco::CharucoBoard):
// squaresX x squaresY squares of squareSize, the top-left square black; a marker of markerSize centred in every
// white square (those with (x + y) odd), marker ids 0, 1, ... row-major from the top-left. Corner id i (the
// (squaresX - 1) x (squaresY - 1) inner corners, row-major) sits at ((i % (squaresX - 1) + 1) s,
// (i / (squaresX - 1) + 1) s). The markers give every corner its identity, so a partial view keeps its ids.
//
//   target_type: charuco
//   squaresX: 7                  # squares along x
//   squaresY: 5                  # squares along y
//   squareSizeMeters: 0.04
//   markerSizeMeters: 0.03       # < squareSize
//   arucoDictionary: DICT_4X4_50 # optional; any cv::aruco predefined DICT_4X4_50 .. DICT_7X7_1000 name
struct CharucoLayout {
  int squares_x = 0;
  int squares_y = 0;
  double square_size_mm = 0;
  double marker_size_mm = 0;
  std::string dictionary = "DICT_4X4_50";

  int InnerCols() const noexcept { return squares_x - 1; }
  int InnerRows() const noexcept { return squares_y - 1; }
  int NumMarkers() const noexcept { return squares_x * squares_y / 2; }
  // White margin between a marker and its square's edge: the corner's point symmetry holds within this radius.
  double MarginMm() const noexcept { return 0.5 * (square_size_mm - marker_size_mm); }
};

// The cv::aruco predefined dictionary of a name ("DICT_4X4_50"), and its number of markers; nullopt if unknown.
std::optional<int> ArucoDictionaryId(std::string_view name);
int ArucoDictionarySize(int dictionary_id);

struct TargetExtent {
  double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
  double WidthMm() const noexcept { return max_x_mm - min_x_mm; }
  double HeightMm() const noexcept { return max_y_mm - min_y_mm; }
};

struct TargetDescription {
  std::variant<CheckerboardLayout, AprilGridLayout, CharucoLayout> layout;
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

// Parses a target description (YAML text); `name` is used in error messages. Throws util::InputError.
TargetDescription ParseTargetDescription(std::string_view yaml_text, const std::string& name);
// Reads and parses a target description file. Throws util::InputError "PATH: KEY: problem".
TargetDescription LoadTargetDescription(const std::string& path);

}  // namespace topocal::calib
