// A map's PNG file (plot/map_image.h, WriteMapPng) and a page of maps' (plot/map_page.h): maps drawn on stepped
// palettes in a palette PNG, any other in true colour.
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "imageio/image_file.h"
#include "imageio/indexed_png.h"
#include "plot/map_image.h"
#include "plot/map_png.h"
#include "util/io.h"

namespace topocal::plot {
namespace {

using Bgr = std::array<std::uint8_t, 3>;

// A stepped map's colour bar shows one colour per band; more than this many colours on the bar is a continuous
// palette (or bands too fine to see), kept in true colour. 2 x 90 band colours and their hatched forms, 52 greys
// and the few overlay colours fit a 256-entry palette.
constexpr std::size_t kMaxBarColours = 90;
constexpr int kGreyStep = 5;  // 0, 5, ..., 255: the anti-aliased edges of black text and lines on white

Bgr HalfWhite(Bgr c) {  // the hatching beyond the supported radius (plot/map_image.cc)
  for (auto& v : c) v = static_cast<std::uint8_t>((v + 256) / 2);
  return c;
}

// The colours stepped maps are drawn in: their bars' band colours and their hatched forms, the no-data grey (both
// forms), the marker's magenta, and greys for text, lines and contours. Empty when a bar is not stepped.
std::vector<Bgr> MapPalette(int width_px, const std::vector<std::uint8_t>& bgr, const std::vector<PixelRect>& bars) {
  std::set<Bgr> bar;
  for (const PixelRect& r : bars) {
    const int x = r.x + r.width / 2;
    for (int y = r.y; y < r.y + r.height; ++y) {
      const std::size_t k = 3 * (static_cast<std::size_t>(y) * width_px + x);
      bar.insert({bgr[k], bgr[k + 1], bgr[k + 2]});
      if (bar.size() > kMaxBarColours) return {};
    }
  }
  std::set<Bgr> seen;
  std::vector<Bgr> palette;
  const auto add = [&](const Bgr& c) {
    if (seen.insert(c).second) palette.push_back(c);
  };
  for (const Bgr& c : bar) add(c);
  for (const Bgr& c : bar) add(HalfWhite(c));
  add(NoDataColour());
  add(HalfWhite(NoDataColour()));
  add(kMarkerBgr);
  add({30, 30, 30});  // contour lines
  for (int g = 0; g <= 255; g += kGreyStep) {
    const auto v = static_cast<std::uint8_t>(g);
    add({v, v, v});
  }
  return palette;
}

// Each pixel as the index of its colour in the palette, or of the nearest entry (squared RGB distance, the first of
// equals): the anti-aliased edges of lines and letters over the colours.
std::vector<std::uint8_t> Indices(const std::vector<std::uint8_t>& bgr, const std::vector<Bgr>& palette) {
  std::unordered_map<std::uint32_t, std::uint8_t> index_of;
  std::vector<std::uint8_t> out(bgr.size() / 3);
  // A map is runs of one colour: the previous pixel's answer is reused without a lookup.
  std::uint32_t last_key = 0xFFFFFFFFu;
  std::uint8_t last_index = 0;
  for (std::size_t k = 0; k < out.size(); ++k) {
    const std::uint8_t* p = &bgr[3 * k];
    const std::uint32_t key = (std::uint32_t{p[0]} << 16) | (std::uint32_t{p[1]} << 8) | p[2];
    if (key == last_key) {
      out[k] = last_index;
      continue;
    }
    auto it = index_of.find(key);
    if (it == index_of.end()) {
      int best = 0, best_d = 1 << 30;
      for (std::size_t i = 0; i < palette.size(); ++i) {
        int d = 0;
        for (int ch = 0; ch < 3; ++ch) d += (palette[i][ch] - p[ch]) * (palette[i][ch] - p[ch]);
        if (d < best_d) best_d = d, best = static_cast<int>(i);
      }
      it = index_of.emplace(key, static_cast<std::uint8_t>(best)).first;
    }
    out[k] = last_index = it->second;
    last_key = key;
  }
  return out;
}

}  // namespace

std::vector<unsigned char> MapPictureBytes(int width_px, int height_px, const std::vector<std::uint8_t>& bgr,
                                           const std::vector<PixelRect>& bars, const std::string& name) {
  const std::vector<Bgr> palette = MapPalette(width_px, bgr, bars);
  if (palette.empty()) {
    return imageio::EncodePng(cv::Mat(height_px, width_px, CV_8UC3, const_cast<std::uint8_t*>(bgr.data())), name);
  }
  std::vector<std::array<std::uint8_t, 3>> rgb;
  for (const Bgr& c : palette) rgb.push_back({c[2], c[1], c[0]});
  return imageio::EncodeIndexedPng(width_px, height_px, Indices(bgr, palette), rgb);
}

void WriteMapPng(const std::string& path, const GridMap& map, const MapImageOptions& options) {
  const MapImage image = RenderMap(map, options);
  const auto png = MapPictureBytes(image.width_px, image.height_px, image.bgr, {image.colour_bar}, path);
  util::WriteFileAtomic(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

}  // namespace topocal::plot
