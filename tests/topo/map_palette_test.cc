// The palettes of the maps' scales (plot/map_image.h): stepped as clinical displays step them, one colour per
// contour band on the plot and on the colour bar alike; elevation symmetric about zero.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <set>

#include "plot/map_image.h"

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

}  // namespace
}  // namespace topocal::plot
