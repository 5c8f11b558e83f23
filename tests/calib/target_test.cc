#include "calib/target.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <string>

#include "calib/target_drawing.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

// Parsed lengths are metres * 1000 in double arithmetic: exact to a few ulps.
constexpr double kLengthTolMm = 1e-12;

const char* kKalibrCheckerboard =
    "target_type: 'checkerboard' #gridtype\n"
    "targetCols: 9               #number of internal chessboard corners\n"
    "targetRows: 6               #number of internal chessboard corners\n"
    "rowSpacingMeters: 0.025     #size of one chessboard square [m]\n"
    "colSpacingMeters: 0.03      #size of one chessboard square [m]\n";

const char* kKalibrAprilGrid =
    "target_type: 'aprilgrid' #gridtype\n"
    "tagCols: 6               #number of apriltags\n"
    "tagRows: 5               #number of apriltags\n"
    "tagSize: 0.088           #size of apriltag, edge to edge [m]\n"
    "tagSpacing: 0.3          #ratio of space between tags to tagSize\n";

std::string ErrorOf(const std::string& yaml) {
  try {
    ParseTargetDescription(yaml, "T.yaml");
  } catch (const util::InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(TargetDescription, ParsesKalibrCheckerboardWithoutYamlHeader) {
  const auto target = ParseTargetDescription(kKalibrCheckerboard, "cb.yaml");
  ASSERT_TRUE(target.IsCheckerboard());
  const auto& b = std::get<CheckerboardLayout>(target.layout);
  EXPECT_EQ(b.cols, 9);
  EXPECT_EQ(b.rows, 6);
  EXPECT_NEAR(b.row_spacing_mm, 25.0, kLengthTolMm);
  EXPECT_NEAR(b.col_spacing_mm, 30.0, kLengthTolMm);
  EXPECT_EQ(target.CornerIds().size(), 54u);
}

TEST(TargetDescription, AcceptsYamlHeader) {
  const auto target = ParseTargetDescription(std::string("%YAML:1.0\n---\n") + kKalibrCheckerboard, "cb.yaml");
  EXPECT_TRUE(target.IsCheckerboard());
}

TEST(TargetDescription, ParsesKalibrAprilGridWithTopocalDefaults) {
  const auto target = ParseTargetDescription(kKalibrAprilGrid, "ag.yaml");
  ASSERT_FALSE(target.IsCheckerboard());
  const auto& g = std::get<AprilGridLayout>(target.layout);
  EXPECT_EQ(g.tag_cols, 6);
  EXPECT_EQ(g.tag_rows, 5);
  EXPECT_NEAR(g.tag_size_mm, 88.0, kLengthTolMm);
  EXPECT_NEAR(g.tag_spacing_ratio, 0.3, kLengthTolMm);
  EXPECT_EQ(g.family, "tag36h11");
  EXPECT_EQ(g.first_tag_id, 0);
  EXPECT_EQ(target.CornerIds().size(), 120u);

  const auto with_id = ParseTargetDescription(std::string(kKalibrAprilGrid) + "tagFamily: tag36h11\nfirstTagId: 40\n",
                                              "ag.yaml");
  EXPECT_EQ(std::get<AprilGridLayout>(with_id.layout).first_tag_id, 40);
}

TEST(TargetDescription, RejectsBadFilesNamingFileAndKey) {
  const std::string cb = kKalibrCheckerboard;
  EXPECT_EQ(ErrorOf("target_type: checkerboard\ntargetCols: 9\nrowSpacingMeters: 0.02\ncolSpacingMeters: 0.02\n"),
            "T.yaml: targetRows: missing");
  EXPECT_EQ(ErrorOf(cb + "tagSize: 0.02\n"), "T.yaml: tagSize: unknown key");
  EXPECT_EQ(ErrorOf(std::string(kKalibrAprilGrid) + "tagBorderBits: 3\n"),
            "T.yaml: tagBorderBits: must be 1 or 2 (Kalibr prints 2), got 3");
  EXPECT_EQ(ErrorOf(std::regex_replace(cb, std::regex("targetCols: 9"), "targetCols: nine")),
            "T.yaml: targetCols: not an integer");
  EXPECT_EQ(ErrorOf(std::regex_replace(cb, std::regex("targetCols: 9"), "targetCols: 9.5")),
            "T.yaml: targetCols: not an integer");
  EXPECT_EQ(ErrorOf(std::regex_replace(cb, std::regex("targetRows: 6"), "targetRows: 0")),
            "T.yaml: targetRows: must be in [1, 1000], got 0");
  EXPECT_EQ(ErrorOf(std::regex_replace(cb, std::regex("0.025"), "-0.025")),
            "T.yaml: rowSpacingMeters: must be a positive number, got -0.025");
  EXPECT_EQ(ErrorOf(std::regex_replace(cb, std::regex("'checkerboard'"), "circlegrid")),
            "T.yaml: target_type: must be checkerboard, aprilgrid or charuco, got 'circlegrid'");
  EXPECT_EQ(ErrorOf(std::string(kKalibrAprilGrid) + "tagFamily: tag25h9\n"),
            "T.yaml: tagFamily: only tag36h11 is supported, got 'tag25h9'");
  EXPECT_EQ(ErrorOf(std::string(kKalibrAprilGrid) + "firstTagId: 580\n"),
            "T.yaml: firstTagId: ids 580..609 exceed tag36h11's 587 codes");
  EXPECT_EQ(ErrorOf(std::string(kKalibrAprilGrid) + "firstTagId: -1\n"),
            "T.yaml: firstTagId: must be in [0, 1000000], got -1");
  EXPECT_EQ(ErrorOf("   \n"), "T.yaml: empty target description");
  EXPECT_NE(ErrorOf("target_type: [unclosed\n").find("T.yaml: "), std::string::npos);
  EXPECT_THROW(LoadTargetDescription("/nonexistent/T.yaml"), util::InputError);
}

TEST(TargetDescription, CornerPositionsFollowTheDrawnOrdering) {
  const auto cb = ParseTargetDescription(kKalibrCheckerboard, "cb.yaml");
  EXPECT_TRUE(cb.CornerMm(0)->isApprox(Eigen::Vector3d(0, 0, 0)));
  EXPECT_TRUE(cb.CornerMm(1)->isApprox(Eigen::Vector3d(30, 0, 0)));
  EXPECT_TRUE(cb.CornerMm(9)->isApprox(Eigen::Vector3d(0, 25, 0)));
  EXPECT_TRUE(cb.CornerMm(53)->isApprox(Eigen::Vector3d(240, 125, 0)));
  EXPECT_FALSE(cb.CornerMm(54).has_value());
  EXPECT_FALSE(cb.CornerMm(-1).has_value());

  const auto ag = ParseTargetDescription(kKalibrAprilGrid, "ag.yaml");
  const double pitch = 88.0 * 1.3;
  // Tag 7 = column 1, row 1 counted from the bottom (Kalibr), i.e. y0 = 3 pitches down from the top of 5 rows:
  // corners 0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left (y down).
  const double y0 = 3 * pitch;
  EXPECT_TRUE(ag.CornerMm(28)->isApprox(Eigen::Vector3d(pitch, y0 + 88, 0)));
  EXPECT_TRUE(ag.CornerMm(29)->isApprox(Eigen::Vector3d(pitch + 88, y0 + 88, 0)));
  EXPECT_TRUE(ag.CornerMm(30)->isApprox(Eigen::Vector3d(pitch + 88, y0, 0)));
  EXPECT_TRUE(ag.CornerMm(31)->isApprox(Eigen::Vector3d(pitch, y0, 0)));
  EXPECT_FALSE(ag.CornerMm(120).has_value());
}

TEST(TargetPattern, CheckerboardColoursAndQuietBorder) {
  const auto cb = ParseTargetDescription(kKalibrCheckerboard, "cb.yaml");
  const TargetPattern pattern(cb);
  EXPECT_TRUE(pattern.IsBlack(-15, -12.5));   // outer square diagonally before corner 0
  EXPECT_FALSE(pattern.IsBlack(15, -12.5));
  EXPECT_TRUE(pattern.IsBlack(15, 12.5));
  EXPECT_FALSE(pattern.IsBlack(-45, 12.5));   // white border, one square wide
  EXPECT_TRUE(pattern.OnPaper(-45, 12.5));
  EXPECT_FALSE(pattern.OnPaper(-61, 12.5));
}

TEST(TargetPattern, TagsHaveTheirBlackBorderAndDifferentCodes) {
  // tagBorderBits 1: libapriltag's own tags (8 cells, one black ring), no corner squares.
  const auto ag = ParseTargetDescription(std::string(kKalibrAprilGrid) + "tagBorderBits: 1\n", "ag.yaml");
  const TargetPattern pattern(ag);
  ASSERT_EQ(pattern.tag_cells(), 8);
  ASSERT_EQ(pattern.tag_bits().size(), 30u);
  for (const auto& bits : pattern.tag_bits()) {
    for (int i = 0; i < 8; ++i) {
      EXPECT_TRUE(bits[static_cast<size_t>(i)]);           // top row
      EXPECT_TRUE(bits[static_cast<size_t>(56 + i)]);      // bottom row
      EXPECT_TRUE(bits[static_cast<size_t>(8 * i)]);       // left column
      EXPECT_TRUE(bits[static_cast<size_t>(8 * i + 7)]);   // right column
    }
  }
  EXPECT_NE(pattern.tag_bits()[0], pattern.tag_bits()[1]);
  EXPECT_TRUE(pattern.IsBlack(1.0, 1.0));          // border cell of the top-left tag
  EXPECT_FALSE(pattern.IsBlack(88.0 + 5.0, 10.0));  // gap between two tags
  EXPECT_FALSE(pattern.IsBlack(88.0 + 5.0, 88.0 + 5.0));  // gap crossing: no corner square
}

TEST(TargetPattern, KalibrLayoutHasTwoCellBorderAndCornerSquares) {
  const auto ag = ParseTargetDescription(kKalibrAprilGrid, "ag.yaml");
  const auto& grid = std::get<AprilGridLayout>(ag.layout);
  ASSERT_EQ(grid.border_bits, 2);  // Kalibr's YAML unchanged means Kalibr's print
  const TargetPattern pattern(ag);
  ASSERT_EQ(pattern.tag_cells(), 10);
  for (const auto& bits : pattern.tag_bits()) {
    for (int i = 0; i < 10; ++i) {
      for (const int ring : {0, 1, 8, 9}) {
        EXPECT_TRUE(bits[static_cast<size_t>(ring * 10 + i)]);  // two rows at the top and the bottom
        EXPECT_TRUE(bits[static_cast<size_t>(i * 10 + ring)]);  // two columns at the left and the right
      }
    }
  }
  // Kalibr numbers rows from the bottom of the print: tag 0 is bottom-left, tag 24 (row 4 of 5) at the top-left.
  EXPECT_NEAR(grid.TagOriginMm(0).y(), 4 * 88.0 * 1.3, kLengthTolMm * 1e3);
  EXPECT_NEAR(grid.TagOriginMm(24).y(), 0.0, kLengthTolMm);
  EXPECT_NEAR(ag.CornerMm(4 * 24 + 3)->norm(), 0.0, kLengthTolMm);  // top-left corner of tag 24 is the origin
  // Corner squares of side gap = 26.4 mm fill every gap crossing, the outer ones included.
  const double gap = 0.3 * 88.0, pitch = 1.3 * 88.0;
  EXPECT_TRUE(pattern.IsBlack(pitch - 0.5 * gap, pitch - 0.5 * gap));
  EXPECT_TRUE(pattern.IsBlack(-0.5 * gap, -0.5 * gap));
  EXPECT_TRUE(pattern.IsBlack(6 * pitch - 0.5 * gap, 5 * pitch - 0.5 * gap));
  EXPECT_FALSE(pattern.IsBlack(pitch - 0.5 * gap, 0.5 * 88.0));  // gap beside a tag stays white
  EXPECT_FALSE(pattern.IsBlack(-1.5 * gap, -0.5 * gap));          // beyond the outer squares
  const TargetExtent extent = ag.PatternExtent();
  EXPECT_NEAR(extent.min_x_mm, -gap, kLengthTolMm * 1e3);
  EXPECT_NEAR(extent.max_x_mm, 6 * pitch, kLengthTolMm * 1e3);
}

TEST(TargetDrawing, SvgIsInMillimetresWithPaperMargin) {
  const auto cb = ParseTargetDescription(kKalibrCheckerboard, "cb.yaml");
  const std::string svg = TargetSvg(cb);
  // 10 x 7 squares of 30 x 25 mm plus one square of margin on each side: 360 x 225 mm.
  EXPECT_NE(svg.find("width=\"360.0000mm\" height=\"225.0000mm\""), std::string::npos);
  // Black squares: 35 of the 70 squares, plus the white paper rectangle.
  const std::regex rect("<rect");
  const std::ptrdiff_t rects = std::distance(std::sregex_iterator(svg.begin(), svg.end(), rect), std::sregex_iterator());
  EXPECT_EQ(rects, 36);
}

TEST(TargetDrawing, PngIsAtPhysicalScaleAndSvgPngWriteAtomically) {
  const auto ag = ParseTargetDescription(kKalibrAprilGrid, "ag.yaml");
  const double dpi = 50.0;
  const cv::Mat raster = RasterizeTarget(ag, dpi);
  const TargetExtent paper = ag.PaperExtent();
  EXPECT_EQ(raster.cols, static_cast<int>(std::round(paper.WidthMm() * dpi / 25.4)));
  EXPECT_EQ(raster.rows, static_cast<int>(std::round(paper.HeightMm() * dpi / 25.4)));
  EXPECT_EQ(raster.at<uint8_t>(0, 0), 255);  // quiet border

  const auto dir = std::filesystem::temp_directory_path() / "topocal_target_test";
  std::filesystem::create_directories(dir);
  const std::string png = (dir / "grid.png").string(), svg = (dir / "grid.svg").string();
  WriteTargetDrawing(ag, png, dpi);
  WriteTargetDrawing(ag, svg, dpi);
  const cv::Mat read = cv::imread(png, cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(cv::norm(read, raster, cv::NORM_INF), 0.0);
  EXPECT_NE(util::ReadFile(svg).find("<!-- tag 29 -->"), std::string::npos);
  EXPECT_THROW(WriteTargetDrawing(ag, (dir / "grid.jpg").string(), dpi), util::InputError);
  EXPECT_THROW(WriteTargetDrawing(ag, png, -1.0), util::InputError);
  EXPECT_THROW(WriteTargetDrawing(ag, (dir / "huge.png").string(), 1e6), util::InputError);
  EXPECT_FALSE(std::filesystem::exists(dir / "huge.png"));
}

}  // namespace
}  // namespace topocal::calib
