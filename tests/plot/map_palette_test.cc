// The palettes of the maps' scales (plot/map_image.h): stepped as clinical displays step them, one colour per
// contour band on the plot and on the colour bar alike; elevation symmetric about zero.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <set>
#include <string>
#include <unistd.h>

#include "imageio/image_file.h"
#include "plot/map_image.h"
#include "util/io.h"

namespace topocal::plot {
namespace {

using Bgr = std::array<std::uint8_t, 3>;

// Values equal to x (mm) over [lo, hi] x [lo, hi].
GridMap RampAlongX(int n, double lo, double hi, const char* unit) {
  GridMap g;
  g.x_min_mm = g.y_min_mm = lo;
  g.x_max_mm = g.y_max_mm = hi;
  g.nx = g.ny = n;
  g.unit = unit;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) g.values.push_back(lo + (hi - lo) * i / (n - 1));
  }
  return g;
}

bool IsContour(const Bgr& c) { return c == Bgr{30, 30, 30}; }

// The bar's row of value v (value_max at its top row, value_min at its bottom row).
int BarRow(const MapImage& img, double v) {
  return img.colour_bar.y + static_cast<int>(std::lround((img.value_max - v) / (img.value_max - img.value_min) *
                                                         (img.colour_bar.height - 1)));
}

// On the standard scale (35.5-50.5 D in 1.5 D steps) a ramp over 36-50 D is drawn in exactly the 10 band colours,
// each the scale's colour at its band's middle; the colour bar shows the same colour between the same two ticks, and
// the plot's colour at a band's middle value is the bar's colour there: colour and numbers agree.
TEST(MapPalette, AStepScaleHasOneColourPerBandOnThePlotAndTheBar) {
  const GridMap ramp = RampAlongX(141, 36.0, 50.0, "D");
  const MapScale scale = SelectMapScale({&ramp}, StandardPowerScale());
  MapImageOptions o;
  o.size_px = 400;
  ApplyMapScale(scale, &o);
  EXPECT_TRUE(o.stepped_palette);
  const MapImage img = RenderMap(ramp, o);
  constexpr int kBands = 10;
  std::set<Bgr> band_colours;
  for (int k = 0; k < kBands; ++k) band_colours.insert(ScaleColour(ColourScale::kTurbo, (k + 0.5) / kBands));
  std::set<Bgr> seen;
  int off_palette = 0;
  for (int y = img.plot.y; y < img.plot.y + img.plot.height; ++y) {
    for (int x = img.plot.x; x < img.plot.x + img.plot.width; ++x) {
      const Bgr c = img.Bgr(x, y);
      if (IsContour(c) || c == NoDataColour()) continue;
      seen.insert(c);
      off_palette += band_colours.count(c) ? 0 : 1;
    }
  }
  EXPECT_EQ(off_palette, 0);
  EXPECT_EQ(seen, band_colours);  // a continuous palette shows ~200 colours here
  const int bar_x = img.colour_bar.x + img.colour_bar.width / 2;
  const int y_mid = img.plot.y + img.plot.height / 2;
  for (int k = 0; k < kBands; ++k) {
    const double lo = kStandardPowerLowD + k * kStandardPowerStepD, mid = lo + 0.5 * kStandardPowerStepD;
    const Bgr expected = ScaleColour(ColourScale::kTurbo, (k + 0.5) / kBands);
    // Every bar row strictly between the band's two tick rows.
    for (int r = BarRow(img, lo + kStandardPowerStepD) + 1; r < BarRow(img, lo); ++r) {
      ASSERT_EQ(img.Bgr(bar_x, r), expected) << "band " << k << " row " << r;
    }
    if (mid < 36.0 || mid > 50.0) continue;  // outside the ramp
    EXPECT_EQ(img.Bgr(img.PixelOf(mid, 0.0)[0], y_mid), expected) << "band " << k;
  }
}

// Values beyond a stepped scale take its end bands' colours, and so do the bar's end rows.
TEST(MapPalette, BeyondTheScaleIsTheEndBandsColour) {
  const GridMap ramp = RampAlongX(61, 30.0, 56.0, "D");
  MapImageOptions o;
  o.size_px = 300;
  ApplyMapScale(SelectMapScale({&ramp}, StandardPowerScale()), &o);
  const MapImage img = RenderMap(ramp, o);
  const int y = img.plot.y + img.plot.height / 2;
  const Bgr bottom = ScaleColour(ColourScale::kTurbo, 0.05), top = ScaleColour(ColourScale::kTurbo, 0.95);
  EXPECT_EQ(img.Bgr(img.PixelOf(31.7, 0.0)[0], y), bottom);
  EXPECT_EQ(img.Bgr(img.PixelOf(54.2, 0.0)[0], y), top);
  const int bar_x = img.colour_bar.x + img.colour_bar.width / 2;
  EXPECT_EQ(img.Bgr(bar_x, img.colour_bar.y), top);
  EXPECT_EQ(img.Bgr(bar_x, img.colour_bar.y + img.colour_bar.height - 1), bottom);
}

// Elevation is drawn symmetric about zero: -30..+120 um on [-m, m] with m the largest |value| rounded out to a
// tick, zero at the palette's middle (a band boundary: the bands just above and below it are mirror colours); a
// near-flat field keeps the minimum span.
TEST(MapPalette, ElevationIsSymmetricAboutZero) {
  const GridMap elev = RampAlongX(61, -30.0, 120.0, "\u00b5m");
  const MapScale s = SelectMapScale({&elev}, SymmetricScale(kMinNormalisedSpanUm));
  EXPECT_EQ(s.value_min, -s.value_max);
  EXPECT_GE(s.value_max, 120.0);
  EXPECT_LE(s.value_max, 150.0);  // 120 rounded out to the ticks of 50 um
  EXPECT_NE(s.label.find("symmetric about 0"), std::string::npos) << s.label;
  const int bands = static_cast<int>(std::lround((s.value_max - s.value_min) / s.contour_step));
  EXPECT_EQ(bands % 2, 0);  // zero is a band boundary
  MapImageOptions o;
  o.size_px = 300;
  ApplyMapScale(s, &o);
  const MapImage img = RenderMap(elev, o);
  const int y = img.plot.y + img.plot.height / 2;
  const double h = 0.5 * s.contour_step;
  const Bgr above = img.Bgr(img.PixelOf(h, 0.0)[0], y), below = img.Bgr(img.PixelOf(-h, 0.0)[0], y);
  EXPECT_EQ(above, ScaleColour(ColourScale::kTurbo, 0.5 + 0.5 / bands));
  EXPECT_EQ(below, ScaleColour(ColourScale::kTurbo, 0.5 - 0.5 / bands));
  // A 20 nm residual: the 1 um minimum span, still about zero.
  const GridMap flat = RampAlongX(11, -0.01, 0.02, "\u00b5m");
  const MapScale f = SelectMapScale({&flat}, SymmetricScale(kMinNormalisedSpanUm));
  EXPECT_EQ(f.value_min, -f.value_max);
  EXPECT_GE(f.value_max - f.value_min, kMinNormalisedSpanUm);
  EXPECT_LE(f.value_max - f.value_min, 2 * kMinNormalisedSpanUm);
}

// A stepped map is written as a palette PNG: colour type 3, every band colour (plain and hatched) exactly as drawn,
// nearly every pixel identical (the rest anti-aliased edges of letters and lines, given the nearest of the map's
// colours: a grey moves by at most 2 levels), in a fraction of the true-colour bytes. A continuous map stays in true colour, pixel for pixel.
TEST(MapPalette, AStepMapIsAPalettePngWithItsColoursExact) {
  const GridMap ramp = RampAlongX(141, 36.0, 50.0, "D");
  MapImageOptions o;
  o.size_px = 400;
  ApplyMapScale(SelectMapScale({&ramp}, StandardPowerScale()), &o);
  o.markers = {{43.0, 43.0}};
  o.supported_radius_mm = 5.0;  // about (0, 0): the whole ramp lies beyond it, hatched
  o.eye = "OD";
  o.legend = {"magenta dot: a marker"};
  const auto dir = std::filesystem::temp_directory_path() / ("topocal_palette_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto written = [&](const MapImageOptions& options) {
    const std::string path = (dir / "map.png").string();
    WriteMapPng(path, ramp, options);
    return util::ReadFile(path);
  };
  const std::string png = written(o);
  EXPECT_EQ(static_cast<int>(png[25]), 3);  // IHDR colour type: palette
  const MapImage img = RenderMap(ramp, o);
  const cv::Mat decoded = imageio::DecodeImage(png, imageio::Channels::kAsStored, "map.png");
  ASSERT_EQ(decoded.type(), CV_8UC3);
  ASSERT_EQ(decoded.cols, img.width_px);
  ASSERT_EQ(decoded.rows, img.height_px);
  std::set<Bgr> bands;
  for (int k = 0; k < 10; ++k) {
    Bgr c = ScaleColour(ColourScale::kTurbo, (k + 0.5) / 10);
    bands.insert(c);
    for (auto& v : c) v = static_cast<std::uint8_t>((v + 256) / 2);
    bands.insert(c);
  }
  long same = 0, band_pixels = 0, band_changed = 0, grey_moved_far = 0;
  for (int y = 0; y < img.height_px; ++y) {
    for (int x = 0; x < img.width_px; ++x) {
      const cv::Vec3b d = decoded.at<cv::Vec3b>(y, x);
      const Bgr drawn = img.Bgr(x, y);
      const bool equal = d[0] == drawn[0] && d[1] == drawn[1] && d[2] == drawn[2];
      same += equal ? 1 : 0;
      if (bands.count(drawn)) ++band_pixels, band_changed += equal ? 0 : 1;
      if (drawn[0] == drawn[1] && drawn[1] == drawn[2]) grey_moved_far += std::abs(d[0] - drawn[0]) > 2 ? 1 : 0;
    }
  }
  EXPECT_GT(band_pixels, 50000);
  EXPECT_EQ(band_changed, 0);
  const double share = static_cast<double>(same) / (img.width_px * img.height_px);
  // Measured 0.974: the others are mostly letters' anti-aliased greys, moved to the palette's greys (every 5th level).
  EXPECT_GT(share, 0.95) << share;
  EXPECT_EQ(grey_moved_far, 0);
  const std::vector<unsigned char> true_colour =
      imageio::EncodePng(cv::Mat(img.height_px, img.width_px, CV_8UC3, const_cast<std::uint8_t*>(img.bgr.data())), "t");
  EXPECT_LT(png.size(), true_colour.size() / 3) << png.size() << " vs " << true_colour.size();  // measured 1/18
  // The continuous palette: true colour (type 2), the pixels as drawn.
  MapImageOptions continuous;
  continuous.size_px = 200;
  const std::string tc = written(continuous);
  EXPECT_EQ(static_cast<int>(tc[25]), 2);
  const MapImage ci = RenderMap(ramp, continuous);
  const cv::Mat cd = imageio::DecodeImage(tc, imageio::Channels::kAsStored, "map.png");
  EXPECT_EQ(cv::norm(cd, cv::Mat(ci.height_px, ci.width_px, CV_8UC3, const_cast<std::uint8_t*>(ci.bgr.data())),
                     cv::NORM_INF),
            0.0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace topocal::plot
