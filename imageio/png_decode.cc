#include "imageio/png_decode.h"

#include <png.h>

#include <csetjmp>
#include <cstdint>
#include <cstring>
#include <opencv2/imgcodecs.hpp>  // the IMREAD_ constants only
#include <vector>

#include "imageio/container_check.h"

namespace topocal::imageio {
namespace {

// Whether the file is one of the PNGs this decodes (png_decode.h), from its bytes: the signature, an IHDR of 8- or
// 16-bit grey (0), RGB (2) or RGBA (6) without interlacing, a size within cv::imdecode's own limits (so that OpenCV
// would not refuse it before decoding), and no chunk that would take OpenCV's decoder down a path not taken here:
// a palette or transparency (expanded to colour or alpha), EXIF (orientation), animation, Apple's CgBI, or any
// other critical chunk. The container check (container_check.h) has already walked the chunks.
bool IsCommonPng(std::string_view b) {
  static constexpr std::string_view kSignature("\x89PNG\r\n\x1a\n", 8);
  if (b.size() < 33 || b.substr(0, 8) != kSignature || BigEndian32(b, 8) != 13 || b.substr(12, 4) != "IHDR") {
    return false;
  }
  const std::uint64_t width = BigEndian32(b, 16), height = BigEndian32(b, 20);
  const int bit_depth = static_cast<unsigned char>(b[24]), colour_type = static_cast<unsigned char>(b[25]);
  const int interlace = static_cast<unsigned char>(b[28]);
  // CV_IO_MAX_IMAGE_WIDTH, _HEIGHT and _PIXELS of OpenCV 4.6 (loadsave.cpp, validateInputImageSize).
  constexpr std::uint64_t kMaxSide = std::uint64_t{1} << 20, kMaxPixels = std::uint64_t{1} << 30;
  if (width == 0 || height == 0 || width > kMaxSide || height > kMaxSide || width * height > kMaxPixels) return false;
  if ((bit_depth != 8 && bit_depth != 16) || (colour_type != 0 && colour_type != 2 && colour_type != 6) ||
      interlace != 0) {
    return false;
  }
  for (std::size_t at = 8; at + 12 <= b.size();) {
    const std::uint64_t length = BigEndian32(b, at);
    const std::string_view type = b.substr(at + 4, 4);
    if (type == "IEND") return true;
    const bool critical = type[0] >= 'A' && type[0] <= 'Z';
    if ((critical && type != "IHDR" && type != "IDAT") || type == "tRNS" || type == "eXIf" || type == "acTL" ||
        type == "fcTL" || type == "fdAT") {
      return false;
    }
    at += 12 + length;
  }
  return false;  // no IEND: left to OpenCV
}

// OpenCV's PngDecoder::readDataFromBuf: libpng reads the file from memory; past its end is a libpng error.
struct MemoryReader {
  const unsigned char* data;
  std::size_t size;
  std::size_t pos;
};

void ReadFromMemory(png_structp png, png_bytep out, png_size_t n) {
  auto* reader = static_cast<MemoryReader*>(png_get_io_ptr(png));
  if (reader->pos + n > reader->size) {
    png_error(png, "PNG input buffer is incomplete");
    return;
  }
  std::memcpy(out, reader->data + reader->pos, n);
  reader->pos += n;
}

// The two steps below return through libpng's longjmp on a libpng error (its default handler prints
// "libpng error: ..." on stderr first, as it does in OpenCV), so nothing in them has a destructor.

// OpenCV's PngDecoder::readHeader: the header chunks, the IHDR's fields.
bool ReadHeader(png_structp png, png_infop info, MemoryReader* reader, png_uint_32* width, png_uint_32* height,
                int* bit_depth, int* colour_type) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_read_fn(png, reader, &ReadFromMemory);
  png_read_info(png, info);
  png_get_IHDR(png, info, width, height, bit_depth, colour_type, nullptr, nullptr, nullptr);
  return true;
}

// OpenCV's PngDecoder::readData for an image of `channels` channels of `depth` (the types IsCommonPng allows: no
// palette, no grey below 8 bits), into `rows`.
bool ReadPixels(png_structp png, png_infop info, png_infop end, int bit_depth, int colour_type, int depth,
                int channels, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  const bool colour = channels > 1;
  if (depth == CV_8U && bit_depth == 16) {
    png_set_strip_16(png);
  } else {
    png_set_swap(png);  // 16-bit samples are big-endian in the file; this is a little-endian machine (x86-64)
  }
  if (channels < 4) {
    png_set_strip_alpha(png);
  } else {
    png_set_tRNS_to_alpha(png);
  }
  if ((colour_type & PNG_COLOR_MASK_COLOR) && colour) {
    png_set_bgr(png);
  } else if (colour) {
    png_set_gray_to_rgb(png);
  } else {
    png_set_rgb_to_gray(png, 1, 0.299, 0.587);
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  png_read_image(png, rows);
  png_read_end(png, end);
  return true;
}

struct PngReadStructs {
  png_structp png = nullptr;
  png_infop info = nullptr, end = nullptr;
  ~PngReadStructs() {
    if (png) png_destroy_read_struct(&png, info ? &info : nullptr, end ? &end : nullptr);
  }
};

}  // namespace

std::optional<cv::Mat> DecodeCommonPng(std::string_view bytes, int imread_flags) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "ReadPixels swaps 16-bit samples as OpenCV does here");
  if ((imread_flags != cv::IMREAD_UNCHANGED && imread_flags != cv::IMREAD_GRAYSCALE) || !IsCommonPng(bytes)) {
    return std::nullopt;
  }
  PngReadStructs s;
  s.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (!s.png) return cv::Mat();
  s.info = png_create_info_struct(s.png);
  s.end = png_create_info_struct(s.png);
  if (!s.info || !s.end) return cv::Mat();
  MemoryReader reader{reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), 0};
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, colour_type = 0;
  if (!ReadHeader(s.png, s.info, &reader, &width, &height, &bit_depth, &colour_type)) return cv::Mat();
  // The type OpenCV's decoder reports for the file, and the one cv::imdecode makes of it for the flags.
  int channels = colour_type == PNG_COLOR_TYPE_RGB ? 3 : colour_type == PNG_COLOR_TYPE_RGB_ALPHA ? 4 : 1;
  int depth = bit_depth == 16 ? CV_16U : CV_8U;
  if (imread_flags == cv::IMREAD_GRAYSCALE) {
    channels = 1;
    depth = CV_8U;
  }
  cv::Mat image(static_cast<int>(height), static_cast<int>(width), CV_MAKETYPE(depth, channels));
  std::vector<png_bytep> rows(height);
  for (png_uint_32 y = 0; y < height; ++y) rows[y] = image.ptr(static_cast<int>(y));
  if (!ReadPixels(s.png, s.info, s.end, bit_depth, colour_type, depth, channels, rows.data())) return cv::Mat();
  return image;
}

}  // namespace topocal::imageio
