#pragma once
// The PNGs topocal reads and writes — 8- or 16-bit grey, colour or colour with alpha, not interlaced, with neither
// palette, transparency, EXIF nor animation chunks — decoded in this process. Loading OpenCV's codecs (the plugin,
// imgcodecs_abi.h) costs a process ~0.1 s of dynamic loading for the 112 libraries behind Debian's
// libopencv_imgcodecs (docs/performance.md, "Start-up"). A plain file (IHDR, IDAT and IEND only, a valid stream of
// the image's size) is inflated by libdeflate and unfiltered here (png_decode.cc says why); any other goes to
// libpng, called as OpenCV 4.6's PngDecoder calls it (readHeader, then readData) for the same cv::imread flags.
// Either way the pixels are cv::imdecode's, and on data libpng refuses so are its messages on stderr and the empty
// result (ImageFile.CommonPngDecodesAsOpenCvDoes and EveryRowFilterAndPixelSizeDecodesAsOpenCvDoes compare the two).
// Every other image, and every PNG whose header or chunks fall outside that list, is left to OpenCV through the
// plugin.
#include <optional>
#include <string_view>

#include <opencv2/core/mat.hpp>

namespace topocal::imageio {

// nullopt: not such a PNG (the caller decodes it through OpenCV). Otherwise what cv::imdecode(bytes, imread_flags)
// returns for it (IMREAD_UNCHANGED or IMREAD_GRAYSCALE; other flags give nullopt): the image, or an empty Mat when
// libpng refuses the data. Throws cv::Exception where cv::imdecode would (the image's memory cannot be had).
std::optional<cv::Mat> DecodeCommonPng(std::string_view bytes, int imread_flags);
// Whether DecodeCommonPng decodes these bytes (rather than returning nullopt) for the flags above.
bool IsInProcessPng(std::string_view bytes) noexcept;

}  // namespace topocal::imageio
