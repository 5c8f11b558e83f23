#pragma once
// The PNGs topocal reads and writes — 8- or 16-bit grey, colour or colour with alpha, not interlaced, with neither
// palette, transparency, EXIF nor animation chunks — decoded by libpng in this process. Loading OpenCV's codecs
// (the plugin, imgcodecs_abi.h) costs a process ~0.1 s of dynamic loading for the 112 libraries behind Debian's
// libopencv_imgcodecs (docs/performance.md, "Start-up"); for these files the decoder is OpenCV's own: the same
// libpng, called as OpenCV 4.6's PngDecoder calls it (readHeader, then readData) for the same cv::imread flags, so
// the pixels, libpng's messages on stderr and an empty result on a libpng error are cv::imdecode's
// (ImageFile.CommonPngDecodesAsOpenCvDoes compares the two over every type and flag). Every other image, and every
// PNG whose header or chunks fall outside that list, is left to OpenCV through the plugin.
#include <optional>
#include <string_view>

#include <opencv2/core/mat.hpp>

namespace topocal::imageio {

// nullopt: not such a PNG (the caller decodes it through OpenCV). Otherwise what cv::imdecode(bytes, imread_flags)
// returns for it (IMREAD_UNCHANGED or IMREAD_GRAYSCALE; other flags give nullopt): the image, or an empty Mat when
// libpng refuses the data. Throws cv::Exception where cv::imdecode would (the image's memory cannot be had).
std::optional<cv::Mat> DecodeCommonPng(std::string_view bytes, int imread_flags);

}  // namespace topocal::imageio
