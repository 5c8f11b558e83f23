#include "imageio/png_decode.h"

#include <libdeflate.h>
#include <png.h>

#include <csetjmp>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <opencv2/imgcodecs.hpp>  // the IMREAD_ constants only
#include <string>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

// ---- The fast path: libdeflate and the PNG filters, for the files that leave nothing to libpng's judgement --------
//
// Why by hand: libpng inflates through zlib; libdeflate inflates the same stream in a fraction of the time, and no
// PNG library in Debian 12 inflates through it (libpng and libspng both use zlib). bench/imageio_bench.cc times this
// path against cv::imdecode on the same bytes (docs/performance.md has the figures). What remains of a PNG decoder is the chunk walk and the five row filters of the PNG specification (ISO/IEC 15948,
// section 9), below. The pixels are the specification's, so the same as libpng's (ImageFile tests compare them with
// cv::imdecode over every type, flag, filter and pixel size). Whatever this path does
// not accept outright — an ancillary chunk (libpng may warn about it), a zlib header with a small window, a stream
// that does not end exactly at the image's size, a bad filter byte, a CRC that fails — goes down the libpng path
// below, which gives OpenCV's pixels, messages and refusals.

struct PngLayout {
  std::uint32_t width = 0, height = 0;
  int bit_depth = 0, colour_type = 0;
  std::vector<std::string_view> idat;  // the IDAT chunks' data: together, one zlib stream
  std::size_t idat_bytes = 0;
};

// The layout of a PNG of IHDR, consecutive IDATs and IEND only, every CRC right; nullopt otherwise.
std::optional<PngLayout> ParsePlainPng(std::string_view b) {
  PngLayout out;
  out.width = BigEndian32(b, 16);
  out.height = BigEndian32(b, 20);
  out.bit_depth = static_cast<unsigned char>(b[24]);
  out.colour_type = static_cast<unsigned char>(b[25]);
  // Compression and filter method 0; libpng's default user limits on the size (PNG_USER_WIDTH_MAX, _HEIGHT_MAX).
  if (b[26] != 0 || b[27] != 0 || out.width > 1000000 || out.height > 1000000) return std::nullopt;
  for (std::size_t at = 8; at + 12 <= b.size();) {
    const std::size_t length = BigEndian32(b, at);
    if (length > b.size() - at - 12) return std::nullopt;
    const std::string_view type = b.substr(at + 4, 4);
    const auto* crc_start = reinterpret_cast<const unsigned char*>(b.data() + at + 4);
    if (libdeflate_crc32(0, crc_start, 4 + length) != BigEndian32(b, at + 8 + length)) return std::nullopt;
    // Only IHDR first, IDATs and IEND: the IDATs are then consecutive, and any other chunk, which libpng may warn
    // about, leaves the file to libpng.
    if (type == "IDAT") {
      out.idat.push_back(b.substr(at + 8, length));
      out.idat_bytes += length;
    } else if (type == "IEND") {
      return out.idat_bytes > 0 ? std::optional(std::move(out)) : std::nullopt;
    } else if (type != "IHDR") {
      return std::nullopt;
    } else if (at != 8) {
      return std::nullopt;
    }
    at += 12 + length;
  }
  return std::nullopt;
}

std::uint8_t Paeth(int a, int b, int c) {
  const int pa = std::abs(b - c), pb = std::abs(a - c), pc = std::abs(a + b - 2 * c);
  return static_cast<std::uint8_t>(pa <= pb && pa <= pc ? a : pb <= pc ? b : c);
}

#if defined(__SSE2__)
// The Sub filter reversed over a row's first whole 16-byte blocks, kBpp 1, 2, 4 or 8 bytes per pixel; returns the
// bytes done. x[i] += x[i - kBpp] is a running sum along each of the kBpp interleaved byte sequences: within a block
// a prefix sum in the register (log2(16 / kBpp) shifted adds), plus the block before's last pixel broadcast. Written
// here because no Debian library exports one (libpng's SSE2 filters are internal and cover 3 and 4 bytes per pixel;
// a camera's 16-bit grey frame is 2, and OpenCV writes its PNGs with this filter).
template <int kBpp>
std::size_t UnfilterSubBlocks(std::uint8_t* x, std::size_t n) {
  static_assert(kBpp == 1 || kBpp == 2 || kBpp == 4 || kBpp == 8);
  __m128i carry = _mm_setzero_si128();
  std::size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(x + i));
    v = _mm_add_epi8(v, _mm_slli_si128(v, kBpp));
    if constexpr (kBpp < 8) v = _mm_add_epi8(v, _mm_slli_si128(v, 2 * kBpp));
    if constexpr (kBpp < 4) v = _mm_add_epi8(v, _mm_slli_si128(v, 4 * kBpp));
    if constexpr (kBpp < 2) v = _mm_add_epi8(v, _mm_slli_si128(v, 8 * kBpp));
    v = _mm_add_epi8(v, carry);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(x + i), v);
    if constexpr (kBpp == 8) {
      carry = _mm_unpackhi_epi64(v, v);
    } else if constexpr (kBpp == 4) {
      carry = _mm_shuffle_epi32(v, 0xFF);
    } else {
      const __m128i w = _mm_shufflehi_epi16(kBpp == 1 ? _mm_unpackhi_epi8(v, v) : v, 0xFF);  // word 7 in 4..7
      carry = _mm_unpackhi_epi64(w, w);
    }
  }
  return i;
}
#endif

// One row's filter reversed in place (`x`, n bytes; `prev` the row above, unfiltered), kBpp bytes per pixel. The
// left, up and up-left bytes of each of the kBpp interleaved sequences are carried in registers, so that no load
// waits on the store before it.
template <int kBpp>
void UnfilterRow(std::uint8_t filter, std::uint8_t* x, const std::uint8_t* prev, std::size_t n) {
  std::uint8_t left[kBpp] = {}, up_left[kBpp] = {};
  switch (filter) {
    case 1: {
      std::size_t i = 0;
#if defined(__SSE2__)
      if constexpr (kBpp == 1 || kBpp == 2 || kBpp == 4 || kBpp == 8) i = UnfilterSubBlocks<kBpp>(x, n);
      if (i > 0) std::memcpy(left, x + i - kBpp, kBpp);
#endif
      for (; i < n; i += kBpp) {
        for (int c = 0; c < kBpp; ++c) x[i + c] = left[c] = static_cast<std::uint8_t>(x[i + c] + left[c]);
      }
      return;
    }
    case 2:
      for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<std::uint8_t>(x[i] + prev[i]);
      return;
    case 3:
      for (std::size_t i = 0; i < n; i += kBpp) {
        for (int c = 0; c < kBpp; ++c) {
          x[i + c] = left[c] = static_cast<std::uint8_t>(x[i + c] + ((left[c] + prev[i + c]) >> 1));
        }
      }
      return;
    case 4:
      for (std::size_t i = 0; i < n; i += kBpp) {
        for (int c = 0; c < kBpp; ++c) {
          const std::uint8_t up = prev[i + c];
          x[i + c] = left[c] = static_cast<std::uint8_t>(x[i + c] + Paeth(left[c], up, up_left[c]));
          up_left[c] = up;
        }
      }
      return;
    default: return;  // 0: none
  }
}

// Reverses the row filters in place: `rows` holds each row as its filter byte and `row_bytes` filtered bytes, `bpp`
// bytes per pixel (1, 2, 3, 4, 6 or 8). Each row is handed to `emit(y, row)` as soon as the row below no longer needs
// it, while it is still in cache: one pass over the image instead of two. False for a filter byte above 4.
template <int kBpp, typename Emit>
bool UnfilterRows(std::uint8_t* rows, std::size_t height, std::size_t row_bytes, Emit& emit) {
  const std::vector<std::uint8_t> zeros(row_bytes, 0);
  const std::uint8_t* prev = zeros.data();
  for (std::size_t y = 0; y < height; ++y) {
    std::uint8_t* row = rows + y * (row_bytes + 1);
    if (row[0] > 4) return false;
    UnfilterRow<kBpp>(row[0], row + 1, prev, row_bytes);
    if (y > 0) emit(y - 1, prev);
    prev = row + 1;
  }
  if (height > 0) emit(height - 1, prev);
  return true;
}

template <typename Emit>
bool Unfilter(std::uint8_t* rows, std::size_t height, std::size_t row_bytes, std::size_t bpp, Emit emit) {
  switch (bpp) {
    case 1: return UnfilterRows<1>(rows, height, row_bytes, emit);
    case 2: return UnfilterRows<2>(rows, height, row_bytes, emit);
    case 3: return UnfilterRows<3>(rows, height, row_bytes, emit);
    case 4: return UnfilterRows<4>(rows, height, row_bytes, emit);
    case 6: return UnfilterRows<6>(rows, height, row_bytes, emit);
    case 8: return UnfilterRows<8>(rows, height, row_bytes, emit);
    default: return false;
  }
}

// 16-bit big-endian samples into the machine's (little-endian) order, `out` <= `in` allowed to overlap: each block is
// read whole into a local buffer before it is written, which also lets the compiler vectorise the swap (it cannot
// prove overlapping pointers safe and would fall back to one sample at a time).
void SwapSamples16(const std::uint8_t* in, std::size_t samples, std::uint8_t* out) {
  constexpr std::size_t kBlock = 32;  // samples
  std::uint16_t block[kBlock];
  std::size_t i = 0;
  for (; i + kBlock <= samples; i += kBlock) {
    std::memcpy(block, in + 2 * i, sizeof block);
    for (auto& v : block) v = static_cast<std::uint16_t>((v << 8) | (v >> 8));
    std::memcpy(out + 2 * i, block, sizeof block);
  }
  for (; i < samples; ++i) {
    const auto value = static_cast<std::uint16_t>((in[2 * i] << 8) | in[2 * i + 1]);
    std::memcpy(out + 2 * i, &value, 2);
  }
}

// One unfiltered row (big-endian samples, R G B (A) order) into the image's row, as OpenCV's decoder delivers it:
// 16-bit samples in the machine's order (or their high byte for an 8-bit result), colour as B G R (A). In place:
// `out` may overlap `in` from below (out <= in), so each sample or pixel is read whole before it is written.
void ConvertRow(const std::uint8_t* in, std::size_t width, int channels, bool sixteen, int depth, std::uint8_t* out) {
  const std::size_t samples = width * static_cast<std::size_t>(channels);
  if (channels == 1 && !sixteen) {
    std::memmove(out, in, samples);
  } else if (channels == 1 && depth == CV_16U) {
    SwapSamples16(in, samples, out);
  } else if (channels == 1) {
    for (std::size_t i = 0; i < samples; ++i) out[i] = in[2 * i];  // the high byte: libpng's strip_16
  } else {
    const std::size_t bytes = sixteen ? 2 : 1, pixel_bytes = bytes * static_cast<std::size_t>(channels);
    for (std::size_t i = 0; i < width; ++i) {
      std::uint8_t pixel[8];
      std::memcpy(pixel, in + i * pixel_bytes, pixel_bytes);
      for (int c = 0; c < channels; ++c) {
        const std::uint8_t* sample = pixel + (c < 3 ? 2 - c : c) * bytes;  // R G B -> B G R; alpha stays
        if (sixteen) {
          const auto value = static_cast<std::uint16_t>((sample[0] << 8) | sample[1]);
          std::memcpy(out + (i * channels + c) * 2, &value, 2);
        } else {
          out[i * channels + c] = sample[0];
        }
      }
    }
  }
}

// The image by the fast path; nullopt when the file is not one it takes (the libpng path decides).
std::optional<cv::Mat> DecodePlainPng(std::string_view bytes, int imread_flags) {
  const int colour_type = static_cast<unsigned char>(bytes[25]);
  // Colour read as grey is libpng's own weighted conversion: left to it.
  if (colour_type != 0 && imread_flags != cv::IMREAD_UNCHANGED) return std::nullopt;
  const auto layout = ParsePlainPng(bytes);
  if (!layout || layout->idat_bytes < 2) return std::nullopt;
  // One zlib stream. Its buffers are cv::Mat's, as the image's: a program that asks for huge pages for image buffers
  // (imageio/large_buffers.h) gets them for these too; on small pages their faults cost more than the inflating.
  cv::Mat joined;
  std::string_view stream = layout->idat[0];
  if (layout->idat.size() > 1) {
    joined.create(1, static_cast<int>(layout->idat_bytes), CV_8UC1);
    std::size_t at = 0;
    for (const auto chunk : layout->idat) {
      std::memcpy(joined.data + at, chunk.data(), chunk.size());
      at += chunk.size();
    }
    stream = std::string_view(reinterpret_cast<const char*>(joined.data), layout->idat_bytes);
  }
  if (stream.size() < 2) return std::nullopt;
  // zlib header: deflate with a 32 KiB window, no preset dictionary (libpng handles smaller windows its own way).
  const auto cmf = static_cast<unsigned char>(stream[0]), flg = static_cast<unsigned char>(stream[1]);
  if (cmf != 0x78 || (cmf * 256 + flg) % 31 != 0 || (flg & 0x20)) return std::nullopt;
  const int channels = colour_type == 2 ? 3 : colour_type == 6 ? 4 : 1;
  const bool sixteen = layout->bit_depth == 16;
  const std::size_t bpp = static_cast<std::size_t>(channels) * (sixteen ? 2 : 1);
  const std::size_t row_bytes = layout->width * bpp, height = layout->height;
  const std::size_t raw_bytes = height * (row_bytes + 1);
  // Deflate expands at most 1032:1: a header promising more than the stream can hold is libpng's to refuse (and
  // nothing is allocated for it here).
  if (raw_bytes / 1032 > stream.size() || raw_bytes >= std::size_t{1} << 31) return std::nullopt;
  // The stream is inflated into the image's own buffer, a few rows longer than the image so that the filter bytes
  // fit; each row is then moved down into place (never onto bytes still to be read): one image-sized buffer, as
  // libpng's path has.
  const int depth = sixteen && imread_flags == cv::IMREAD_UNCHANGED ? CV_16U : CV_8U;
  const std::size_t out_row_bytes = layout->width * channels * (depth == CV_16U ? 2 : 1);
  const std::size_t rows = (raw_bytes + out_row_bytes - 1) / out_row_bytes;
  cv::Mat buffer(static_cast<int>(rows), static_cast<int>(layout->width), CV_MAKETYPE(depth, channels));
  std::uint8_t* raw = buffer.data;
  std::unique_ptr<libdeflate_decompressor, void (*)(libdeflate_decompressor*)> inflater(
      libdeflate_alloc_decompressor(), &libdeflate_free_decompressor);
  if (!inflater) return std::nullopt;
  std::size_t in_used = 0, out_made = 0;
  if (libdeflate_zlib_decompress_ex(inflater.get(), stream.data(), stream.size(), raw, raw_bytes, &in_used,
                                    &out_made) != LIBDEFLATE_SUCCESS ||
      in_used != stream.size() || out_made != raw_bytes) {
    return std::nullopt;
  }
  joined.release();
  // Row y - 1 is moved into place once row y is unfiltered: its place ends at y out_row_bytes <= y row_bytes, below
  // row y's bytes, so no row still needed is overwritten.
  const auto convert = [&](std::size_t y, const std::uint8_t* row) {
    ConvertRow(row, layout->width, channels, sixteen, depth, buffer.ptr(static_cast<int>(y)));
  };
  if (!Unfilter(raw, height, row_bytes, bpp, convert)) return std::nullopt;
  return buffer.rowRange(0, static_cast<int>(height));
}

}  // namespace

bool IsInProcessPng(std::string_view bytes) noexcept { return IsCommonPng(bytes); }

std::optional<cv::Mat> DecodeCommonPng(std::string_view bytes, int imread_flags) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "ReadPixels swaps 16-bit samples as OpenCV does here");
  if ((imread_flags != cv::IMREAD_UNCHANGED && imread_flags != cv::IMREAD_GRAYSCALE) || !IsCommonPng(bytes)) {
    return std::nullopt;
  }
  if (auto image = DecodePlainPng(bytes, imread_flags)) return image;
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
