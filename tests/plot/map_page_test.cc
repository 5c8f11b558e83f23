// The one-page overview (plot/map_page.h): every map placed pixel for pixel in its cell, the text lines drawn in the
// next cell and wrapped to it, the page written as a palette PNG like the maps.
#include "plot/map_page.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <set>
#include <string>
#include <vector>

#include "imageio/image_file.h"
#include "util/io.h"

namespace topocal::plot {
namespace {

GridMap Disc(double centre_value) {
  GridMap g;
  g.x_min_mm = g.y_min_mm = -4;
  g.x_max_mm = g.y_max_mm = 4;
  g.nx = g.ny = 41;
  g.unit = "D";
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const double x = -4 + 0.2 * i, y = -4 + 0.2 * j;
      g.values.push_back(x * x + y * y <= 16 ? centre_value + 0.1 * x * y : NAN);
    }
  }
  return g;
}

// Dark (text) pixels in rows [y0, y1) of a rectangle.
int DarkPixels(const MapPage& p, const PixelRect& r, int y0, int y1) {
  int n = 0;
  for (int y = std::max(r.y, y0); y < std::min(r.y + r.height, y1); ++y) {
    for (int x = r.x; x < r.x + r.width; ++x) {
      const std::size_t k = 3 * (static_cast<std::size_t>(y) * p.width_px + x);
      n += p.bgr[k] < 128 && p.bgr[k + 1] < 128 && p.bgr[k + 2] < 128 ? 1 : 0;
    }
  }
  return n;
}

TEST(MapPage, TheMapsArePlacedAsDrawnAndTheNumbersBesideThem) {
  const std::vector<GridMap> grids = {Disc(43.0), Disc(44.0), Disc(41.0)};
  MapImageOptions o;
  o.size_px = 200;
  ApplyMapScale(SelectMapScale({&grids[0], &grids[1], &grids[2]}, StandardPowerScale()), &o);
  std::vector<MapImage> maps;
  for (const GridMap& g : grids) maps.push_back(RenderMap(g, o));
  const std::string long_line =
      "capture: 610 of 624 spots identified (98 % visible), 605 usable; no sector missing; 3 unidentified blobs "
      "(glints, lashes, skin); 0 identities refused as ambiguous";
  const MapPage page = ComposeMapPage(maps, "Overview: eye OD (right)", {"sim-K 44.13 D / 40.28 D", long_line});
  ASSERT_EQ(page.panels.size(), 3u);
  // Two columns: axial and tangential side by side, elevation below the axial map, the text beside it.
  EXPECT_EQ(page.panels[0].y, page.panels[1].y);
  EXPECT_GT(page.panels[1].x, page.panels[0].x + page.panels[0].width - 1);
  EXPECT_EQ(page.panels[2].x, page.panels[0].x);
  EXPECT_GT(page.panels[2].y, page.panels[0].y + page.panels[0].height - 1);
  EXPECT_EQ(page.text.x, page.panels[1].x);
  EXPECT_EQ(page.text.y, page.panels[2].y);
  for (std::size_t k = 0; k < maps.size(); ++k) {
    const PixelRect& r = page.panels[k];
    ASSERT_EQ(r.width, maps[k].width_px);
    ASSERT_EQ(r.height, maps[k].height_px);
    for (int y = 0; y < r.height; ++y) {
      for (int x = 0; x < r.width; ++x) {
        const std::size_t a = 3 * (static_cast<std::size_t>(r.y + y) * page.width_px + r.x + x);
        const std::size_t b = 3 * (static_cast<std::size_t>(y) * maps[k].width_px + x);
        ASSERT_TRUE(page.bgr[a] == maps[k].bgr[b] && page.bgr[a + 1] == maps[k].bgr[b + 1] &&
                    page.bgr[a + 2] == maps[k].bgr[b + 2])
            << "map " << k << " at " << x << ", " << y;
      }
    }
  }
  // The long line is wrapped to the cell (no word lost), every line drawn; the title above the maps.
  ASSERT_GE(page.text_lines.size(), 3u);
  std::string joined;
  for (std::size_t k = 1; k < page.text_lines.size(); ++k) joined += (k > 1 ? " " : "") + page.text_lines[k];
  EXPECT_EQ(joined, long_line);
  EXPECT_GT(DarkPixels(page, page.text, page.text.y, page.text.y + page.text.height), 500);
  EXPECT_GT(DarkPixels(page, {0, 0, page.width_px, page.panels[0].y}, 0, page.panels[0].y), 200);
  EXPECT_THROW(ComposeMapPage({}, "t", {}), util::InputError);

  // Written as the maps are: a palette PNG, every colour of the maps' bars exactly where the page has it.
  ASSERT_EQ(page.colour_bars.size(), 3u);
  const auto path = std::filesystem::temp_directory_path() / ("topocal_page_" + std::to_string(::getpid()) + ".png");
  WriteMapPagePng(path.string(), page);
  const std::string png = util::ReadFile(path.string());
  std::filesystem::remove(path);
  EXPECT_EQ(static_cast<int>(png[25]), 3);  // IHDR colour type: palette
  const cv::Mat decoded = imageio::DecodeImage(png, imageio::Channels::kAsStored, "page.png");
  ASSERT_EQ(decoded.cols, page.width_px);
  ASSERT_EQ(decoded.rows, page.height_px);
  std::set<std::array<std::uint8_t, 3>> bar_colours;
  for (const PixelRect& b : page.colour_bars) {
    for (int y = b.y; y < b.y + b.height; ++y) {
      const std::size_t k = 3 * (static_cast<std::size_t>(y) * page.width_px + b.x + b.width / 2);
      bar_colours.insert({page.bgr[k], page.bgr[k + 1], page.bgr[k + 2]});
    }
  }
  EXPECT_LE(bar_colours.size(), 10u);  // the standard scale's 10 bands
  long band_pixels = 0, changed = 0;
  for (int y = 0; y < page.height_px; ++y) {
    for (int x = 0; x < page.width_px; ++x) {
      const std::size_t k = 3 * (static_cast<std::size_t>(y) * page.width_px + x);
      if (!bar_colours.count({page.bgr[k], page.bgr[k + 1], page.bgr[k + 2]})) continue;
      ++band_pixels;
      const cv::Vec3b d = decoded.at<cv::Vec3b>(y, x);
      changed += d[0] == page.bgr[k] && d[1] == page.bgr[k + 1] && d[2] == page.bgr[k + 2] ? 0 : 1;
    }
  }
  EXPECT_GT(band_pixels, 10000);
  EXPECT_EQ(changed, 0);
}

}  // namespace
}  // namespace topocal::plot
