#include "plot/map_page.h"

#include <fmt/format.h>

#include <algorithm>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string_view>

#include "plot/map_png.h"
#include "plot/map_text.h"
#include "util/io.h"

namespace topocal::plot {
namespace {

constexpr std::size_t kMaxMaps = 8;

}  // namespace

MapPage ComposeMapPage(const std::vector<MapImage>& maps, const std::string& title,
                       const std::vector<std::string>& lines) {
  if (maps.empty() || maps.size() > kMaxMaps) {
    throw util::InputError(fmt::format("ComposeMapPage: {} maps (1 to {})", maps.size(), kMaxMaps));
  }
  int cell_w = 0, cell_h = 0, plot_side = 0;
  for (const MapImage& m : maps) {
    if (m.width_px <= 0 || m.height_px <= 0 || m.bgr.size() != 3u * m.width_px * m.height_px) {
      throw util::InputError("ComposeMapPage: a map without pixels");
    }
    cell_w = std::max(cell_w, m.width_px);
    cell_h = std::max(cell_h, m.height_px);
    plot_side = std::max(plot_side, m.plot.width);
  }
  // The maps' own label size (plot/map_image.cc: 1/20 of the plot side), the title 1.2 times it.
  const Font label{std::max(12, plot_side / 20)}, title_font{label.height_px * 6 / 5};
  const int margin = label.height_px, line_h = label.height_px * 3 / 2;
  const int cells = static_cast<int>(maps.size()) + 1, rows = (cells + 1) / 2;
  const int title_h = 2 * margin + title_font.height_px;
  MapPage page;
  page.width_px = 2 * cell_w + 3 * margin;
  page.height_px = title_h + rows * cell_h + rows * margin;
  cv::Mat img(page.height_px, page.width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  PutCentred(img, title, {page.width_px / 2, margin + title_font.height_px}, title_font);
  const auto cell = [&](int k) {
    return cv::Point(margin + (k % 2) * (cell_w + margin), title_h + (k / 2) * (cell_h + margin));
  };
  for (std::size_t k = 0; k < maps.size(); ++k) {
    const MapImage& m = maps[k];
    const cv::Point at = cell(static_cast<int>(k));
    const cv::Mat src(m.height_px, m.width_px, CV_8UC3, const_cast<std::uint8_t*>(m.bgr.data()));
    src.copyTo(img(cv::Rect(at.x, at.y, m.width_px, m.height_px)));
    page.panels.push_back({at.x, at.y, m.width_px, m.height_px});
    page.colour_bars.push_back({at.x + m.colour_bar.x, at.y + m.colour_bar.y, m.colour_bar.width, m.colour_bar.height});
  }
  const cv::Point text_at = cell(static_cast<int>(maps.size()));
  page.text = {text_at.x, text_at.y, cell_w, cell_h};
  for (const std::string& line : lines) {
    for (std::string& wrapped : WrapText(line, label, cell_w - margin)) page.text_lines.push_back(std::move(wrapped));
  }
  for (std::size_t k = 0; k < page.text_lines.size(); ++k) {
    const int baseline = text_at.y + margin + static_cast<int>(k + 1) * line_h;
    if (baseline > text_at.y + cell_h) break;  // the cell is full: a longer text belongs in the JSON
    PutText(img, page.text_lines[k], {text_at.x + margin / 2, baseline}, label);
  }
  page.bgr.assign(img.datastart, img.dataend);
  return page;
}

void WriteMapPagePng(const std::string& path, const MapPage& page) {
  const auto png = MapPictureBytes(page.width_px, page.height_px, page.bgr, page.colour_bars, path);
  util::WriteFileAtomic(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

}  // namespace topocal::plot
