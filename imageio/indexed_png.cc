#include "imageio/indexed_png.h"

#include <fmt/format.h>
#include <zlib.h>

#include <stdexcept>
#include <string_view>
#include "util/io.h"

namespace topocal::imageio {
namespace {

void Append32(std::vector<unsigned char>* out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<unsigned char>(v >> shift));
}

// A chunk: length, type, data, CRC-32 of type and data.
void AppendChunk(std::vector<unsigned char>* out, std::string_view type, const std::vector<unsigned char>& data) {
  Append32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = out->size();
  out->insert(out->end(), type.begin(), type.end());
  out->insert(out->end(), data.begin(), data.end());
  const auto crc = crc32(0L, out->data() + start, static_cast<uInt>(out->size() - start));
  Append32(out, static_cast<std::uint32_t>(crc));
}

}  // namespace

std::vector<unsigned char> EncodeIndexedPng(int width, int height, const std::vector<std::uint8_t>& indices,
                                            const std::vector<std::array<std::uint8_t, 3>>& palette_rgb) {
  if (width <= 0 || height <= 0 || indices.size() != static_cast<std::size_t>(width) * height) {
    throw util::InputError(fmt::format("EncodeIndexedPng: {} indices for {} x {} pixels", indices.size(), width, height));
  }
  if (palette_rgb.empty() || palette_rgb.size() > 256) {
    throw util::InputError(fmt::format("EncodeIndexedPng: a palette of {} colours (1 to 256)", palette_rgb.size()));
  }
  for (const std::uint8_t i : indices) {
    if (i >= palette_rgb.size()) throw util::InputError(fmt::format("EncodeIndexedPng: index {} beyond the palette", i));
  }
  std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<unsigned char> ihdr;
  Append32(&ihdr, static_cast<std::uint32_t>(width));
  Append32(&ihdr, static_cast<std::uint32_t>(height));
  ihdr.insert(ihdr.end(), {8, 3, 0, 0, 0});  // 8 bits per index, palette, deflate, adaptive filtering, no interlace
  AppendChunk(&png, "IHDR", ihdr);
  std::vector<unsigned char> plte;
  for (const auto& c : palette_rgb) plte.insert(plte.end(), c.begin(), c.end());
  AppendChunk(&png, "PLTE", plte);
  // Each row: filter type 0 (none), then its indices.
  std::vector<unsigned char> raw;
  raw.reserve(static_cast<std::size_t>(width + 1) * height);
  for (int r = 0; r < height; ++r) {
    raw.push_back(0);
    const auto row = indices.begin() + static_cast<std::ptrdiff_t>(r) * width;
    raw.insert(raw.end(), row, row + width);
  }
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<unsigned char> idat(size);
  // zlib's default level: on a unit record's 16 maps (7.4 MB of indices) level 9 took ~510 ms of CPU for 402 KB,
  // level 6 ~60 ms for 436 KB; the last 8 % of bytes are not worth a quarter of a unit's calibration time.
  if (compress2(idat.data(), &size, raw.data(), static_cast<uLong>(raw.size()), Z_DEFAULT_COMPRESSION) != Z_OK) {
    throw std::runtime_error("EncodeIndexedPng: zlib could not compress the image");
  }
  idat.resize(size);
  AppendChunk(&png, "IDAT", idat);
  AppendChunk(&png, "IEND", {});
  return png;
}

}  // namespace topocal::imageio
