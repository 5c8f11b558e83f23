#pragma once
// PNG files of palette images (colour type 3, ISO/IEC 15948), written here because OpenCV's encoder writes true
// colour only: a map drawn in a few dozen colours takes a third of the bytes as indices into its palette. Read back
// by any PNG decoder (OpenCV's gives the palette's colours as BGR).
#include <array>
#include <cstdint>
#include <string>
#include <vector>
#include "util/io.h"

namespace topocal::imageio {

// PNG bytes of a width x height image given as one palette index per pixel (row-major, row 0 at the top) and a
// palette of 1 to 256 colours in RGB order; 8 bits per index, no filter (the PNG specification's advice for palette
// images), zlib at its default level. Throws util::InputError when the sizes disagree or an index lies
// beyond the palette.
std::vector<unsigned char> EncodeIndexedPng(int width, int height, const std::vector<std::uint8_t>& indices,
                                            const std::vector<std::array<std::uint8_t, 3>>& palette_rgb);

}  // namespace topocal::imageio
