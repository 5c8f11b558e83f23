// The map drawing (plot/map_image.h) and the grids topo computes for it (topo/map_grid.h), tested together.
#include "plot/map_image.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "model/surface.h"
#include "topo/map_grid.h"
#include "util/io.h"

namespace topocal::topo {
namespace {

namespace fs = std::filesystem;
using namespace topocal::plot;  // NOLINT: the drawing under test
using Bgr = std::array<std::uint8_t, 3>;

// A pixel's scale position may differ from round(255 t) by one entry: the field goes through float32 and cv::remap,
// which quantises interpolation weights to 1/32 of a grid cell (0.003 mm here, 8e-5 of the range, << 1/255).
constexpr int kScaleIndexTolerance = 1;
// ResamplePolar, linear interpolation across meridians 1 deg apart: error <= max|f''| dtheta^2 / 8; for cos(2 theta)
// that is 4 (pi/180)^2 / 8 = 1.5e-4.
constexpr double kAngularInterpolationTolerance = 4.0 * (M_PI / 180.0) * (M_PI / 180.0) / 8.0;
// A field linear in r is reproduced by linear radial interpolation to rounding.
constexpr double kRadialExactTolerance = 1e-12;

GridMap Ramp(int n, double lo_mm, double hi_mm, bool along_x) {
  GridMap g;
  g.x_min_mm = g.y_min_mm = lo_mm;
  g.x_max_mm = g.y_max_mm = hi_mm;
  g.nx = g.ny = n;
  g.title = "ramp";
  g.unit = "D";
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = lo_mm + (hi_mm - lo_mm) * i / (n - 1), y = lo_mm + (hi_mm - lo_mm) * j / (n - 1);
      g.values.push_back(along_x ? x : y);
    }
  }
  return g;
}

// Index of the scale entry nearest to a colour.
int ScaleIndex(ColourScale s, const Bgr& c) {
  int best = 0;
  int best_d = std::numeric_limits<int>::max();
  for (int i = 0; i < 256; ++i) {
    const Bgr e = ScaleColour(s, i / 255.0);
    int d = 0;
    for (int k = 0; k < 3; ++k) d += (e[k] - c[k]) * (e[k] - c[k]);
    if (d < best_d) best_d = d, best = i;
  }
  return best;
}

bool IsContourPixel(const Bgr& c) { return c[0] == 30 && c[1] == 30 && c[2] == 30; }

TEST(MapImage, ColourBarRunsFromTheLowEndAtTheBottomToTheHighEndAtTheTop) {
  for (ColourScale scale : {ColourScale::kTurbo, ColourScale::kJet}) {
    MapImageOptions o;
    o.scale = scale;
    const MapImage img = RenderMap(Ramp(51, -5, 5, true), o);
    const auto& bar = img.colour_bar;
    const int cx = bar.x + bar.width / 2;
    EXPECT_EQ(img.Bgr(cx, bar.y + bar.height - 1), ScaleColour(scale, 0.0));
    EXPECT_EQ(img.Bgr(cx, bar.y), ScaleColour(scale, 1.0));
    // Both scales run blue (low) to red (high): BGR blue > red at the bottom, red > blue at the top.
    EXPECT_GT(img.Bgr(cx, bar.y + bar.height - 1)[0], img.Bgr(cx, bar.y + bar.height - 1)[2]);
    EXPECT_GT(img.Bgr(cx, bar.y)[2], img.Bgr(cx, bar.y)[0]);
    // Monotone along the bar.
    int previous = 256;
    for (int r = bar.y; r < bar.y + bar.height; ++r) {
      const int idx = ScaleIndex(scale, img.Bgr(cx, r));
      EXPECT_LE(idx, previous) << "row " << r;
      previous = idx;
    }
  }
}

TEST(MapImage, AutomaticRangeIsTheDataRangeRoundedOutToTicks) {
  GridMap g = Ramp(11, 0, 1, true);
  for (auto& v : g.values) v = 41.37 + 3.9 * v;  // 41.37 .. 45.27 D
  const MapImage img = RenderMap(g);
  EXPECT_DOUBLE_EQ(img.value_min, 41.0);   // ticks every 0.5 D (3.9 D / 8 rounded up to 1-2-5)
  EXPECT_DOUBLE_EQ(img.value_max, 45.5);
  EXPECT_DOUBLE_EQ(img.contour_step, 0.5);  // about 10 levels over 4.5 D
  MapImageOptions fixed;
  fixed.value_min = 40.0;
  fixed.value_max = 48.0;
  fixed.contour_step = 0.25;
  const MapImage f = RenderMap(g, fixed);
  EXPECT_DOUBLE_EQ(f.value_min, 40.0);
  EXPECT_DOUBLE_EQ(f.value_max, 48.0);
  EXPECT_DOUBLE_EQ(f.contour_step, 0.25);
}

// Values whose spread is below their own rounding (1e16 + a ramp of 1: a tick step of 0.2 that 1e16 cannot tell
// apart) and identical values: the tick loops are counted, so the map is drawn — with its ends as the bar's labels —
// instead of the loop running for ever.
TEST(MapImage, DegenerateValuesDrawABoundedMap) {
  GridMap g = Ramp(11, 0, 1, true);
  for (auto& v : g.values) v = 1e16 + v;
  const MapImage huge = RenderMap(g);
  EXPECT_FALSE(huge.bgr.empty());
  EXPECT_LE(huge.value_min, 1e16);
  EXPECT_GE(huge.value_max, 1e16 + 1);
  for (auto& v : g.values) v = 43.0;
  const MapImage flat = RenderMap(g);
  EXPECT_FALSE(flat.bgr.empty());
  EXPECT_LT(flat.value_min, flat.value_max);
}

TEST(MapImage, LinearRampMapsMonotonicallyOntoTheScale) {
  MapImageOptions o;
  o.contour_step = -1;  // no contour lines over the colours
  o.value_min = -5.0;
  o.value_max = 5.0;
  const MapImage img = RenderMap(Ramp(101, -5, 5, true), o);
  const int row = img.plot.y + img.plot.height / 2;
  int previous = -1;
  for (int c = 0; c < img.plot.width; ++c) {
    const int idx = ScaleIndex(o.scale, img.Bgr(img.plot.x + c, row));
    EXPECT_GE(idx, previous) << "column " << c;
    previous = idx;
    const double x_mm = -5.0 + (c + 0.5) * 10.0 / img.plot.width;
    const int expected = static_cast<int>(std::lround(255.0 * (x_mm + 5.0) / 10.0));
    EXPECT_NEAR(idx, expected, kScaleIndexTolerance) << "column " << c;
  }
}

TEST(MapImage, YPointsUpAndXToTheRight) {
  MapImageOptions o;
  o.contour_step = -1;
  const MapImage img = RenderMap(Ramp(21, -3, 3, false), o);  // value = y
  const int cx = img.plot.x + img.plot.width / 2;
  EXPECT_GT(ScaleIndex(o.scale, img.Bgr(cx, img.plot.y + 2)), 250);
  EXPECT_LT(ScaleIndex(o.scale, img.Bgr(cx, img.plot.y + img.plot.height - 3)), 5);
}

// The bounding box of the plot pixels that differ between two renders, within a part of the plot (x and y as
// fractions of its width and height).
struct Box {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  bool Empty() const { return x1 < 0; }
};
Box DiffBox(const MapImage& a, const MapImage& b, double fx0, double fx1, double fy0, double fy1) {
  Box box;
  const auto& p = a.plot;
  for (int y = p.y + static_cast<int>(fy0 * p.height); y < p.y + static_cast<int>(fy1 * p.height); ++y) {
    for (int x = p.x + static_cast<int>(fx0 * p.width); x < p.x + static_cast<int>(fx1 * p.width); ++x) {
      if (a.Bgr(x, y) == b.Bgr(x, y)) continue;
      box = {std::min(box.x0, x), std::min(box.y0, y), std::max(box.x1, x), std::max(box.y1, y)};
    }
  }
  return box;
}

// An eye's map says which side is which, in the examiner's view (docs/maps.md): S at the top and I at the bottom
// for both eyes; T on the left and N on the right for OD, mirrored for OS. Checked on the pixels: the labels sit at
// the middles of the plot's edges and nowhere else, OD and OS differ only left and right, and OD's left label is
// pixel for pixel OS's right one (the same letter, T) and the other way round.
TEST(MapImage, AnEyesMapIsLabelledNasalTemporalSuperiorInferior) {
  MapImageOptions o;
  const GridMap g = Ramp(41, -4, 4, true);
  const MapImage none = RenderMap(g, o);
  o.eye = "OD";
  const MapImage od = RenderMap(g, o);
  o.eye = "OS";
  const MapImage os = RenderMap(g, o);
  // Nothing inside the plot changes away from the four edge middles.
  EXPECT_TRUE(DiffBox(none, od, 0.15, 0.85, 0.15, 0.85).Empty());
  for (const auto& [fx0, fx1, fy0, fy1] : {std::array{0.0, 0.15, 0.0, 0.4}, std::array{0.0, 0.15, 0.6, 1.0},
                                           std::array{0.85, 1.0, 0.0, 0.4}, std::array{0.85, 1.0, 0.6, 1.0}}) {
    EXPECT_TRUE(DiffBox(none, od, fx0, fx1, fy0, fy1).Empty()) << fx0 << " " << fy0;  // the corners
  }
  const Box top = DiffBox(none, od, 0.4, 0.6, 0.0, 0.15), bottom = DiffBox(none, od, 0.4, 0.6, 0.85, 1.0);
  const Box left = DiffBox(none, od, 0.0, 0.15, 0.4, 0.6), right = DiffBox(none, od, 0.85, 1.0, 0.4, 0.6);
  for (const Box& b : {top, bottom, left, right}) EXPECT_FALSE(b.Empty());
  // S and I are the same for both eyes; T and N trade places.
  EXPECT_TRUE(DiffBox(od, os, 0.0, 1.0, 0.0, 0.15).Empty());
  EXPECT_TRUE(DiffBox(od, os, 0.0, 1.0, 0.85, 1.0).Empty());
  EXPECT_FALSE(DiffBox(od, os, 0.0, 0.15, 0.4, 0.6).Empty());
  const Box os_right = DiffBox(none, os, 0.85, 1.0, 0.4, 0.6);
  ASSERT_EQ(left.x1 - left.x0, os_right.x1 - os_right.x0);
  ASSERT_EQ(left.y1 - left.y0, os_right.y1 - os_right.y0);
  for (int dy = 0; dy <= left.y1 - left.y0; ++dy) {
    for (int dx = 0; dx <= left.x1 - left.x0; ++dx) {
      ASSERT_EQ(od.Bgr(left.x0 + dx, left.y0 + dy), os.Bgr(os_right.x0 + dx, os_right.y0 + dy)) << dx << " " << dy;
    }
  }
  o.eye = "OU";
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("OD, OS"), std::string::npos);
}

// A keratoconus apex at 62 D: the standard scale draws it in its top colour (50.5 D and up); the extended scale
// holds it (30-67.5 D in 2.5 D steps), and a fitted 0.5 D scale rounds the data out to whole steps.
TEST(MapImage, TheExtendedScaleHoldsAnEctaticApex) {
  GridMap g = Ramp(41, -4, 4, true);
  for (double& v : g.values) v = 51.0 + 2.75 * v;  // 40 to 62 D
  const MapScale standard = SelectMapScale({&g}, StandardPowerScale());
  EXPECT_EQ(standard.value_max, kStandardPowerHighD);
  const MapScale extended = SelectMapScale({&g}, ExtendedPowerScale());
  EXPECT_EQ(extended.value_min, 30.0);
  EXPECT_EQ(extended.value_max, 67.5);
  EXPECT_EQ(extended.contour_step, 2.5);
  EXPECT_GE(extended.value_max, 65.0);  // the reach for ectasia
  const MapScale fitted = SelectMapScale({&g}, FittedStepScale(0.5));
  EXPECT_EQ(fitted.value_min, 40.0);
  EXPECT_EQ(fitted.value_max, 62.0);
  EXPECT_EQ(fitted.contour_step, 0.5);
}

TEST(MapImage, NoDataIsLightGreyAndDistinctFromThePage) {
  GridMap g = Ramp(41, -4, 4, true);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx / 2; ++i) g.values[j * g.nx + i] = std::numeric_limits<double>::quiet_NaN();
  }
  const MapImage img = RenderMap(g);
  const int row = img.plot.y + img.plot.height / 2;
  EXPECT_EQ(img.Bgr(img.plot.x + img.plot.width / 4, row), NoDataColour());
  EXPECT_NE(img.Bgr(img.plot.x + 3 * img.plot.width / 4, row), NoDataColour());
  EXPECT_EQ(img.Bgr(0, 0), (Bgr{255, 255, 255}));
  EXPECT_NE(NoDataColour(), (Bgr{255, 255, 255}));
  for (int i = 0; i < 256; ++i) EXPECT_NE(ScaleColour(ColourScale::kTurbo, i / 255.0), NoDataColour());
}

TEST(MapImage, ContourLinesLieOnTheRoundLevels) {
  MapImageOptions o;
  o.contour_step = 1.0;
  const MapImage img = RenderMap(Ramp(101, -5, 5, true), o);  // levels at x = -4 .. 4 mm
  const double px_per_mm = img.plot.width / 10.0;
  std::vector<bool> level_seen(9, false);
  for (int row = img.plot.y + 5; row < img.plot.y + img.plot.height - 5; row += 37) {
    for (int c = 0; c < img.plot.width; ++c) {
      if (!IsContourPixel(img.Bgr(img.plot.x + c, row))) continue;
      const double x_mm = -5.0 + (c + 0.5) / px_per_mm;
      const double level = std::round(x_mm);
      EXPECT_LE(std::abs(x_mm - level) * px_per_mm, 1.0) << "contour pixel off any level at x = " << x_mm;
      if (level >= -4 && level <= 4) level_seen[static_cast<int>(level) + 4] = true;
    }
  }
  for (int k = 0; k < 9; ++k) EXPECT_TRUE(level_seen[k]) << "no line at level " << k - 4;
  // A flat field has no contour line.
  GridMap flat = Ramp(11, -1, 1, true);
  for (auto& v : flat.values) v = 43.27;
  const MapImage f = RenderMap(flat);
  for (int r = 0; r < f.plot.height; ++r) {
    for (int c = 0; c < f.plot.width; ++c) ASSERT_FALSE(IsContourPixel(f.Bgr(f.plot.x + c, f.plot.y + r)));
  }
}

class MapFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("topocal_maps_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(MapFiles, PngIsWrittenAtomicallyWithTheRenderedSize) {
  const GridMap g = Ramp(31, -2, 2, true);
  const std::string path = (dir_ / "ramp.png").string();
  WriteMapPng(path, g);
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 24u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(bytes.substr(12, 4), "IHDR");
  const auto be32 = [&](size_t k) {
    return (static_cast<unsigned char>(bytes[k]) << 24) | (static_cast<unsigned char>(bytes[k + 1]) << 16) |
           (static_cast<unsigned char>(bytes[k + 2]) << 8) | static_cast<unsigned char>(bytes[k + 3]);
  };
  const MapImage img = RenderMap(g);
  EXPECT_EQ(be32(16), static_cast<unsigned>(img.width_px));
  EXPECT_EQ(be32(20), static_cast<unsigned>(img.height_px));
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1);  // no temporary file left beside it
}

TEST_F(MapFiles, UnwritablePathIsInputErrorNamingIt) {
  const std::string path = (dir_ / "missing" / "map.png").string();
  try {
    WriteMapPng(path, Ramp(11, -1, 1, true));
    FAIL() << "no error for " << path;
  } catch (const util::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_THROW(WriteMapCsv(path, Ramp(11, -1, 1, true)), util::InputError);
}

TEST(MapCsv, LongFormatWithUnitInTheHeaderAndEmptyNoData) {
  GridMap g = Ramp(3, -1, 1, true);
  g.unit = "\u00b5m";
  g.values[4] = std::numeric_limits<double>::quiet_NaN();  // centre
  g.values[8] = 0.1 + 0.2;                                   // must read back exactly
  const std::string csv = GridMapCsv(g);
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "x_mm,y_mm,value_um");
  std::vector<std::string> rows;
  while (std::getline(in, line)) rows.push_back(line);
  ASSERT_EQ(rows.size(), 9u);
  EXPECT_EQ(rows[0], "-1,-1,-1");
  EXPECT_EQ(rows[4], "0,0,");
  const double back = std::stod(rows[8].substr(rows[8].rfind(',') + 1));
  EXPECT_EQ(back, 0.1 + 0.2);
  EXPECT_EQ(rows[8].substr(0, 4), "1,1,");
}

TEST(ResamplePolar, ReproducesRadialAndAngularFieldsAndLeavesTheCornersEmpty) {
  PolarField f;
  for (int k = 0; k <= 50; ++k) f.radii_mm.push_back(5.0 * k / 50);
  f.meridians = 360;
  for (int m = 0; m < f.meridians; ++m) {
    for (double r : f.radii_mm) f.values.push_back(r);
  }
  const GridMap radial = ResamplePolar(f, 41, "r", "mm");
  EXPECT_EQ(radial.nx, 41);
  EXPECT_DOUBLE_EQ(radial.x_max_mm, 5.0);
  for (int j = 0; j < 41; ++j) {
    for (int i = 0; i < 41; ++i) {
      const double x = -5.0 + 0.25 * i, y = -5.0 + 0.25 * j;
      const double r = std::hypot(x, y);
      if (r > 5.0) {
        EXPECT_TRUE(std::isnan(radial.At(i, j)));
      } else {
        EXPECT_NEAR(radial.At(i, j), r, kRadialExactTolerance);
      }
    }
  }
  // cos(2 theta): largest along x, smallest along y (meridian 90 deg points to +y, grid row j up).
  f.values.clear();
  for (int m = 0; m < f.meridians; ++m) {
    for (size_t k = 0; k < f.radii_mm.size(); ++k) f.values.push_back(std::cos(2.0 * 2.0 * M_PI * m / f.meridians));
  }
  const GridMap angular = ResamplePolar(f, 41, "cos 2 theta", "");
  for (int j = 0; j < 41; ++j) {
    for (int i = 0; i < 41; ++i) {
      const double x = -5.0 + 0.25 * i, y = -5.0 + 0.25 * j;
      if (std::hypot(x, y) > 5.0 || (x == 0 && y == 0)) continue;
      EXPECT_NEAR(angular.At(i, j), std::cos(2.0 * std::atan2(y, x)), kAngularInterpolationTolerance);
    }
  }
  EXPECT_NEAR(angular.At(20, 40), -1.0, kAngularInterpolationTolerance);  // (0, +5)
}

TEST(MapImage, RejectsInconsistentInput) {
  GridMap g = Ramp(5, -1, 1, true);
  g.values.pop_back();
  std::string why;
  EXPECT_FALSE(g.IsValid(&why));
  EXPECT_THROW(RenderMap(g), util::InputError);
  EXPECT_THROW(GridMapCsv(g), util::InputError);
  MapImageOptions o;
  o.value_min = 2.0;
  o.value_max = 1.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THROW(RenderMap(Ramp(5, -1, 1, true), o), util::InputError);
  PolarField p;
  p.radii_mm = {0.0, 1.0};
  p.meridians = 4;
  p.values = {1.0};
  EXPECT_THROW(ResamplePolar(p, 10, "", ""), util::InputError);
}

// A disc of radius `radius_mm` on an n x n grid holding f(x, y), no data outside.
template <typename F>
GridMap Disc(int n, double radius_mm, const std::string& unit, F f) {
  GridMap g;
  g.x_min_mm = g.y_min_mm = -radius_mm;
  g.x_max_mm = g.y_max_mm = radius_mm;
  g.nx = g.ny = n;
  g.title = "disc";
  g.unit = unit;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = -radius_mm + 2 * radius_mm * i / (n - 1), y = -radius_mm + 2 * radius_mm * j / (n - 1);
      g.values.push_back(std::hypot(x, y) <= radius_mm ? f(x, y) : std::numeric_limits<double>::quiet_NaN());
    }
  }
  return g;
}

// The case for shared map scales (docs/maps.md): a corrected reference sphere (43.258-43.274 D) next to its
// uncorrected map (43-45.5 D, astigmatic).
GridMap CorrectedSphere() {
  return Disc(81, 4.0, "D", [](double x, double y) { return 43.266 + 0.008 * (x * x - y * y) / 16.0; });
}
GridMap UncorrectedSphere() {
  return Disc(81, 4.0, "D", [](double x, double y) { return 44.25 + 1.25 * (x * x - y * y) / 16.0; });
}

TEST(MapScale, SharedScaleHoldsEveryMapOfTheSet) {
  const GridMap a = CorrectedSphere(), b = UncorrectedSphere();
  for (const MapScaleRequest& r : {StandardPowerScale(), NormalisedScale(kMinNormalisedSpanD)}) {
    const MapScale shared = SelectMapScale({&a, &b}, r);
    EXPECT_LE(shared.value_min, 43.0);
    EXPECT_GE(shared.value_max, 45.5);
    // Drawn on both: the same range, contour step and colour bar.
    MapImageOptions o;
    o.size_px = 200;
    ApplyMapScale(shared, &o);
    const MapImage ia = RenderMap(a, o), ib = RenderMap(b, o);
    EXPECT_EQ(ia.value_min, ib.value_min);
    EXPECT_EQ(ia.value_max, ib.value_max);
    EXPECT_EQ(ia.contour_step, ib.contour_step);
    for (int y = ia.colour_bar.y; y < ia.colour_bar.y + ia.colour_bar.height; ++y) {
      ASSERT_EQ(ia.Bgr(ia.colour_bar.x + 2, y), ib.Bgr(ib.colour_bar.x + 2, y));
    }
  }
}

TEST(MapScale, AbsoluteScalesStepFromTheStandardRange) {
  const GridMap sphere = CorrectedSphere();
  const MapScale standard = SelectMapScale({&sphere}, StandardPowerScale());
  EXPECT_DOUBLE_EQ(standard.value_min, 35.5);
  EXPECT_DOUBLE_EQ(standard.value_max, 50.5);
  EXPECT_DOUBLE_EQ(standard.contour_step, 1.5);
  EXPECT_EQ(standard.label, "absolute scale, 1.5 D steps");
  // A steep cornea beyond the range: the standard scale stays fixed (shared by maps drawn one at a time) and the map
  // says how much of it is beyond; asked to, the range widens by whole steps anchored on the standard boundaries.
  const GridMap steep = Disc(41, 4.0, "D", [](double x, double) { return 49.0 + x; });  // 45-53 D
  const MapScale fixed = SelectMapScale({&sphere, &steep}, StandardPowerScale());
  EXPECT_DOUBLE_EQ(fixed.value_max, 50.5);
  MapScaleRequest widen = StandardPowerScale();
  widen.widen_to_data = true;
  const MapScale wide = SelectMapScale({&sphere, &steep}, widen);
  EXPECT_DOUBLE_EQ(wide.value_min, 35.5);
  EXPECT_DOUBLE_EQ(wide.value_max, 53.5);
  MapImageOptions o;
  o.size_px = 200;
  ApplyMapScale(fixed, &o);
  const MapImage clamped = RenderMap(steep, o);
  ApplyMapScale(SelectMapScale({&sphere}, StandardPowerScale()), &o);
  EXPECT_GT(clamped.height_px, RenderMap(sphere, o).height_px);  // one more footer line: "beyond the scale"
  // A user-set step without a standard range: the data in whole steps, at least kMinAbsoluteSteps wide.
  MapScaleRequest user;
  user.kind = MapScaleKind::kAbsolute;
  user.step = 0.5;
  const MapScale u = SelectMapScale({&sphere}, user);
  EXPECT_NEAR((u.value_max - u.value_min) / 0.5, kMinAbsoluteSteps, 1e-9);
  EXPECT_LE(u.value_min, 43.258);
  EXPECT_GE(u.value_max, 43.274);
  EXPECT_NEAR(std::remainder(u.value_min, 0.5), 0.0, 1e-9);
  // Invalid requests say why.
  user.step = 0;
  EXPECT_THROW(SelectMapScale({&sphere}, user), util::InputError);
  user.step = 1.5;
  user.low = 35.0;
  user.high = 50.2;  // not a whole number of steps
  EXPECT_THROW(SelectMapScale({&sphere}, user), util::InputError);
}

// With the minimum span a sphere looks flat: its whole map falls in one or two contour bands and near the middle of
// the palette, where the data's own range (0.016 D) would have spread it from blue to red.
TEST(MapScale, MinimumSpanMakesASphereLookFlat) {
  const GridMap sphere = CorrectedSphere();
  const MapScale own = SelectMapScale({&sphere}, NormalisedScale(0));
  EXPECT_LT(own.value_max - own.value_min, 0.05);
  const MapScale flat = SelectMapScale({&sphere}, NormalisedScale(kMinNormalisedSpanD));
  EXPECT_GE(flat.value_max - flat.value_min, kMinNormalisedSpanD);
  EXPECT_NE(flat.label.find("min. span 1 D"), std::string::npos) << flat.label;
  MapImageOptions o;
  o.size_px = 200;
  o.contour_step = -1;
  ApplyMapScale(flat, &o);
  o.contour_step = -1;  // colours only
  const MapImage img = RenderMap(sphere, o);
  int lo = 255, hi = 0;
  for (int y = img.plot.y; y < img.plot.y + img.plot.height; ++y) {
    for (int x = img.plot.x; x < img.plot.x + img.plot.width; ++x) {
      const Bgr c = img.Bgr(x, y);
      if (c == NoDataColour()) continue;
      const int k = ScaleIndex(ColourScale::kTurbo, c);
      lo = std::min(lo, k), hi = std::max(hi, k);
    }
  }
  // 0.016 D of a >= 1 D range: at most 0.016 x 255 = 4 palette entries (+1 for rounding).
  EXPECT_LE(hi - lo, 5) << lo << ".." << hi;
  EXPECT_GT(lo, 64);
  EXPECT_LT(hi, 192);
}

TEST(MapElevation, ASphereHasZeroElevationAboveItselfAndAProlateCapStandsInFrontAtTheCentre) {
  constexpr double kR = 7.8;
  model::Sphere sphere;
  sphere.radius_mm = kR;
  const GridMap sag = Disc(61, 4.0, "\u00b5m", [&](double x, double y) {
    return (kR - std::sqrt(kR * kR - x * x - y * y)) * 1e3;
  });
  const GridMap elev = ElevationAboveSphere(sag, sphere);
  EXPECT_EQ(elev.unit, "\u00b5m");
  for (double v : elev.values) {
    if (std::isfinite(v)) {
      ASSERT_NEAR(v, 0.0, 1e-9);  // the same sag twice: rounding only
    }
  }
  // A prolate surface (k < 0) flattens towards the edge: it touches the sphere of its apical radius at the centre
  // and stands in front of it (positive elevation; 31 um at 3.87 mm for k = -0.43) towards the edge.
  const GridMap prolate = Disc(61, 4.0, "\u00b5m", [&](double x, double y) {
    const double r2 = x * x + y * y, k = -0.43;
    return r2 / (kR * (1 + std::sqrt(1 - (1 + k) * r2 / (kR * kR)))) * 1e3;
  });
  const GridMap pe = ElevationAboveSphere(prolate, sphere);
  EXPECT_NEAR(pe.At(30, 30), 0.0, 1e-9);
  EXPECT_NEAR(pe.At(59, 30), 31.0, 1.0);
  // Beyond the sphere's equator: no data.
  model::Sphere small;
  small.radius_mm = 2.0;
  const GridMap beyond = ElevationAboveSphere(sag, small);
  EXPECT_TRUE(std::isnan(beyond.At(0, 30)));
  EXPECT_TRUE(std::isfinite(beyond.At(30, 30)));
}

// The clinical overlays are where the options put them: the Kmax marker's pixel has the marker
// colour, the dashed circle lies at the supported radius, the map is hatched beyond it and untouched inside, the
// sim-K axis runs along its angle, and the legend adds its lines.
TEST(MapImage, ClinicalOverlaysAreDrawnWhereTheyClaim) {
  constexpr double kFlatD = 43.0;
  GridMap flat = Disc(241, 6.0, "D", [](double, double) { return kFlatD; });
  MapImageOptions o;
  o.value_min = 35.5;
  o.value_max = 50.5;
  o.contour_step = -1;  // no contour lines: every pixel with data has the one colour
  const MapImage plain = RenderMap(flat, o);
  const Bgr map_colour = ScaleColour(ColourScale::kTurbo, (kFlatD - 35.5) / 15.0);
  o.markers = {{1.3, -2.1}};
  o.axes = {{30.0, 3.0, false}, {120.0, 3.0, true}};
  constexpr double kSupportedMm = 3.7;
  o.supported_radius_mm = kSupportedMm;
  o.legend = {"magenta dot: Kmax", "dashed circle: supported radius"};
  const MapImage img = RenderMap(flat, o);
  // Two more footer lines, the same plot.
  EXPECT_GT(img.height_px, plain.height_px);
  EXPECT_EQ(img.plot.x, plain.plot.x);
  EXPECT_EQ(img.plot.width, plain.plot.width);
  EXPECT_NEAR(img.px_per_mm, plain.plot.width / 12.0, 0.01);

  const auto [kx, ky] = img.PixelOf(1.3, -2.1);
  EXPECT_EQ(img.Bgr(kx, ky), kMarkerBgr);
  // The marker is a few pixels wide, and magenta is nowhere else on the map.
  int magenta = 0;
  for (int r = img.plot.y; r < img.plot.y + img.plot.height; ++r) {
    for (int c = img.plot.x; c < img.plot.x + img.plot.width; ++c) {
      if (img.Bgr(c, r) != kMarkerBgr) continue;
      ++magenta;
      EXPECT_LE(std::hypot(c - kx, r - ky), 0.02 * img.px_per_mm * 12.0) << c << ", " << r;
    }
  }
  EXPECT_GE(magenta, 20);

  // Along rays from the centre through the middle of a dash (dashes 5 of every 8 deg from 0, clockwise on the image
  // as OpenCV counts) that miss the axes and the marker: the map colour up to the circle's white underlay, the dash's
  // black centred on the supported radius, then, beyond, hatched pixels (lighter than the map colour).
  const auto [ox, oy] = img.PixelOf(0.0, 0.0);
  const double r_px = kSupportedMm * img.px_per_mm;
  for (int m : {2, 10, 20, 25}) {
    const double a = -(2.5 + 8.0 * m) * M_PI / 180.0;
    int first_changed = -1, hatched_beyond = 0, black = 0;
    double black_sum = 0;
    const auto sum = [](const Bgr& b) { return b[0] + b[1] + b[2]; };
    // From 0.5 mm: the axes cross at the centre.
    for (int k = static_cast<int>(0.5 * img.px_per_mm); k < static_cast<int>(5.8 * img.px_per_mm); ++k) {
      const int c = ox + static_cast<int>(std::lround(k * std::cos(a)));
      const int r = oy - static_cast<int>(std::lround(k * std::sin(a)));
      const Bgr px = img.Bgr(c, r);
      if (px != map_colour && first_changed < 0) first_changed = k;
      if (sum(px) < 100) ++black, black_sum += k;
      if (k > r_px + 6 && sum(px) > sum(map_colour) + 60) ++hatched_beyond;
    }
    ASSERT_GT(black, 0) << m;
    // The dash is 2 px wide, anti-aliased: its centre within a pixel of the radius.
    EXPECT_NEAR(black_sum / black, r_px, 1.0) << m;
    // Untouched inside: the white underlay (2 px beyond the dash's half width) and anti-aliasing start <= 5 px early.
    EXPECT_GE(first_changed, r_px - 5) << m;
    EXPECT_GT(hatched_beyond, 5) << m;
  }
  // The solid axis at 30 deg: black pixels along it inside the circle.
  int on_axis = 0;
  for (double t = 0.5; t < 2.9; t += 0.1) {
    const auto [c, r] = img.PixelOf(t * std::cos(M_PI / 6), t * std::sin(M_PI / 6));
    on_axis += img.Bgr(c, r)[0] < 40 && img.Bgr(c, r)[1] < 40 && img.Bgr(c, r)[2] < 40;
  }
  EXPECT_GE(on_axis, 20);
}

TEST(MapImage, LabelsAreLegibleAtA4AndAnnotationsAreDrawn) {
  GridMap g = CorrectedSphere();
  g.unit = "\u00b5m\u00b2";
  MapImageOptions o;
  o.size_px = 400;
  const MapImage plain = RenderMap(g, o);
  o.annotations = {"Sim-K 43.27 D @ 90\u00b0 / 43.26 D @ 0\u00b0"};
  o.ring_radii_mm = {1.5};
  const MapImage annotated = RenderMap(g, o);
  // One more line of text above the plot.
  EXPECT_GT(annotated.plot.y, plain.plot.y);
  EXPECT_EQ(annotated.height_px - plain.height_px, annotated.plot.y - plain.plot.y);
  // Printed two across an A4 page (90 mm each), the label em of size/20 px is >= 7 pt (2.5 mm).
  const double mm_per_px = 90.0 / plain.width_px;
  EXPECT_GE(400 / 20.0 * mm_per_px, 2.5) << plain.width_px;
}

}  // namespace
}  // namespace topocal::topo
