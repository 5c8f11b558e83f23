// The one image loader and writer: headers probed right, bombs refused before decoding, every failure one line naming
// the file, PNGs encoded as OpenCV encodes them.
#include "imageio/image_file.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <zlib.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "imageio/png_decode.h"
#include "util/io.h"

namespace topocal::imageio {
namespace {

std::string Encode(const cv::Mat& image, const std::string& ext, std::vector<int> params = {}) {
  std::vector<unsigned char> buffer;
  EXPECT_TRUE(cv::imencode(ext, image, buffer, params));
  return std::string(buffer.begin(), buffer.end());
}

cv::Mat Gradient(int width, int height, int type = CV_8UC1) {
  cv::Mat m(height, width, type);
  cv::randu(m, 0, 255);
  return m;
}

// Message of the InputError `f` throws, or "" if it throws nothing.
template <typename F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const util::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(ImageFile, ProbesPngAndJpegSizesFromTheirHeaders) {
  for (const auto& [w, h] : {std::pair{640, 480}, std::pair{37, 1023}, std::pair{4000, 3}}) {
    const cv::Mat image = Gradient(w, h);
    for (const std::string ext : {".png", ".jpg"}) {
      SCOPED_TRACE(fmt::format("{} {}x{}", ext, w, h));
      const auto size = ProbeStoredSize(Encode(image, ext));
      ASSERT_TRUE(size.has_value());
      EXPECT_EQ(size->width_px, w);
      EXPECT_EQ(size->height_px, h);
    }
  }
  // Progressive JPEG (SOF2) and a colour PNG.
  const auto progressive = ProbeStoredSize(Encode(Gradient(33, 17, CV_8UC3), ".jpg", {cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  ASSERT_TRUE(progressive.has_value());
  EXPECT_EQ(progressive->width_px, 33);
  EXPECT_FALSE(ProbeStoredSize("").has_value());
  EXPECT_FALSE(ProbeStoredSize("BM not a png or jpeg").has_value());
  EXPECT_FALSE(ProbeStoredSize(std::string("\xFF\xD8\xFF", 3)).has_value());  // truncated JPEG
}

TEST(ImageFile, DecodesWhatOpenCvDecodes) {
  const cv::Mat image = Gradient(64, 48);
  const cv::Mat grey = DecodeImage(Encode(image, ".png"), Channels::kGrey, "mem.png");
  EXPECT_EQ(cv::norm(grey, image, cv::NORM_INF), 0.0);
  const cv::Mat colour = Gradient(64, 48, CV_8UC3);
  EXPECT_EQ(DecodeImage(Encode(colour, ".png"), Channels::kAsStored, "mem.png").channels(), 3);
  EXPECT_EQ(DecodeImage(Encode(colour, ".png"), Channels::kGrey, "mem.png").channels(), 1);
  cv::Mat deep(8, 8, CV_16UC1, cv::Scalar(40000));
  EXPECT_EQ(DecodeImage(Encode(deep, ".png"), Channels::kAsStored, "mem.png").depth(), CV_16U);
}

// A PNG chunk (length, type, data, CRC-32 of type and data) inserted after the IHDR, or the IHDR rewritten.
std::string WithChunk(const std::string& png, const std::string& type, const std::string& data) {
  std::string chunk(4, '\0');
  for (int i = 0; i < 4; ++i) chunk[i] = static_cast<char>((data.size() >> (24 - 8 * i)) & 0xFF);
  chunk += type + data;
  const auto crc = crc32(0L, reinterpret_cast<const Bytef*>(chunk.data() + 4), static_cast<uInt>(chunk.size() - 4));
  for (int i = 0; i < 4; ++i) chunk += static_cast<char>((crc >> (24 - 8 * i)) & 0xFF);
  if (type == "IHDR") return png.substr(0, 8) + chunk + png.substr(33);
  return png.substr(0, 33) + chunk + png.substr(33);
}

// A PNG written here by the specification, not by libpng: every row filtered with filter (row mod 5) — none, sub,
// up, average, Paeth — the zlib stream split over three IDAT chunks. `image` as OpenCV holds it (B G R, native
// 16-bit); nothing but IHDR, IDAT and IEND.
std::string SpecPng(const cv::Mat& image) {
  const int channels = image.channels(), bytes = image.depth() == CV_16U ? 2 : 1;
  const std::size_t bpp = static_cast<std::size_t>(channels * bytes), row_bytes = image.cols * bpp;
  std::vector<std::uint8_t> raw, prev(row_bytes, 0);
  for (int y = 0; y < image.rows; ++y) {
    std::vector<std::uint8_t> row(row_bytes);  // R G B (A), big-endian samples
    for (int x = 0; x < image.cols; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int from = channels >= 3 && c < 3 ? 2 - c : c;
        const std::size_t at = (static_cast<std::size_t>(x) * channels + c) * bytes;
        if (bytes == 2) {
          const std::uint16_t v = image.ptr<std::uint16_t>(y)[x * channels + from];
          row[at] = static_cast<std::uint8_t>(v >> 8);
          row[at + 1] = static_cast<std::uint8_t>(v & 0xFF);
        } else {
          row[at] = image.ptr<std::uint8_t>(y)[x * channels + from];
        }
      }
    }
    const int filter = y % 5;
    raw.push_back(static_cast<std::uint8_t>(filter));
    for (std::size_t i = 0; i < row_bytes; ++i) {
      const int a = i >= bpp ? row[i - bpp] : 0, b = prev[i], c = i >= bpp ? prev[i - bpp] : 0;
      const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
      const int paeth = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      const int predictor[5] = {0, a, b, (a + b) / 2, paeth};
      raw.push_back(static_cast<std::uint8_t>(row[i] - predictor[filter]));
    }
    prev = row;
  }
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string stream(size, '\0');
  EXPECT_EQ(compress2(reinterpret_cast<Bytef*>(stream.data()), &size, raw.data(), static_cast<uLong>(raw.size()), 6),
            Z_OK);
  stream.resize(size);
  std::string ihdr(13, '\0');
  for (int i = 0; i < 4; ++i) {
    ihdr[i] = static_cast<char>((image.cols >> (24 - 8 * i)) & 0xFF);
    ihdr[4 + i] = static_cast<char>((image.rows >> (24 - 8 * i)) & 0xFF);
  }
  ihdr[8] = static_cast<char>(bytes * 8);
  ihdr[9] = static_cast<char>(channels == 1 ? 0 : channels == 3 ? 2 : 6);
  // Chunks are inserted after the IHDR: the last IDAT first, then IHDR rewritten.
  std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + std::string(25, '\0') +
                    std::string("\0\0\0\0IEND\xAE\x42\x60\x82", 12);
  const std::size_t third = stream.size() / 3;
  png = WithChunk(png, "IDAT", stream.substr(2 * third));
  png = WithChunk(png, "IDAT", stream.substr(third, third));
  png = WithChunk(png, "IDAT", stream.substr(0, third));
  return WithChunk(png, "IHDR", ihdr);
}

// Every filter type at every pixel size (1, 2, 3, 4, 6, 8 bytes), in a stream over several IDATs: the pixels
// cv::imdecode gives, with both flags.
TEST(ImageFile, EveryRowFilterAndPixelSizeDecodesAsOpenCvDoes) {
  for (const int type : {CV_8UC1, CV_16UC1, CV_8UC3, CV_8UC4, CV_16UC3, CV_16UC4}) {
    cv::Mat image(57, 203, type);
    cv::randu(image, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
    image.rowRange(0, 20) /= 64;  // smoother rows: the predictors matter
    const std::string png = SpecPng(image);
    for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_GRAYSCALE}) {
      SCOPED_TRACE(fmt::format("type {} flags {}", type, flags));
      const auto bytes = cv::Mat(1, static_cast<int>(png.size()), CV_8UC1, const_cast<char*>(png.data()));
      const cv::Mat opencv = cv::imdecode(bytes, flags);
      ASSERT_FALSE(opencv.empty());
      if (flags == cv::IMREAD_UNCHANGED) EXPECT_EQ(cv::norm(opencv, image, cv::NORM_INF), 0.0);
      const std::optional<cv::Mat> here = DecodeCommonPng(png, flags);
      ASSERT_TRUE(here.has_value());
      ASSERT_EQ(here->type(), opencv.type());
      ASSERT_EQ(here->size(), opencv.size());
      ASSERT_TRUE(here->isContinuous());
      EXPECT_EQ(std::memcmp(here->data, opencv.data, opencv.total() * opencv.elemSize()), 0);
    }
  }
}

// The common PNGs are decoded in this process (png_decode.h), by the same libpng calls as OpenCV's decoder: every
// type OpenCV writes, with both flags topocal uses, gives cv::imdecode's pixels bit for bit, and libpng's errors
// the same empty image and the same lines on stderr. Every other PNG is left to OpenCV.
TEST(ImageFile, CommonPngDecodesAsOpenCvDoes) {
  std::vector<std::string> files;
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3, CV_16UC4}) {
    for (const auto& [w, h] : {std::pair{1, 1}, std::pair{37, 11}, std::pair{300, 200}}) {
      cv::Mat image(h, w, type);
      cv::randu(image, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
      if (w > 1) {  // the extremes
        image.row(0).setTo(0);
        image.row(h - 1).setTo(CV_MAT_DEPTH(type) == CV_16U ? 65535 : 255);
      }
      files.push_back(Encode(image, ".png"));
      files.push_back(Encode(image, ".png", {cv::IMWRITE_PNG_COMPRESSION, 9}));
    }
  }
  // Ancillary chunks that change no pixel OpenCV reads: gamma, significant bits, text, physical size.
  const std::string grey = Encode(Gradient(40, 30), ".png");
  files.push_back(WithChunk(grey, "gAMA", std::string("\x00\x00\xB1\x8F", 4)));
  files.push_back(WithChunk(grey, "sBIT", "\x05"));
  files.push_back(WithChunk(grey, "tEXt", std::string("Software\0topocal", 16)));
  files.push_back(WithChunk(Encode(Gradient(40, 30, CV_8UC3), ".png"), "gAMA", std::string("\x00\x00\xB1\x8F", 4)));
  for (std::size_t i = 0; i < files.size(); ++i) {
    for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_GRAYSCALE}) {
      SCOPED_TRACE(fmt::format("file {} flags {}", i, flags));
      const auto bytes = cv::Mat(1, static_cast<int>(files[i].size()), CV_8UC1, files[i].data());
      const cv::Mat opencv = cv::imdecode(bytes, flags);
      const std::optional<cv::Mat> here = DecodeCommonPng(files[i], flags);
      ASSERT_TRUE(here.has_value());
      ASSERT_EQ(here->type(), opencv.type());
      ASSERT_EQ(here->size(), opencv.size());
      ASSERT_TRUE(here->isContinuous() && opencv.isContinuous());
      EXPECT_EQ(std::memcmp(here->data, opencv.data, opencv.total() * opencv.elemSize()), 0);
    }
  }
  // Data libpng refuses (a zlib stream cut inside a whole IDAT chunk, a bad filter type): empty, as cv::imdecode
  // gives it, with what libpng prints.
  cv::Mat flat(64, 64, CV_8UC1, cv::Scalar(7));
  const std::string png = Encode(flat, ".png", {cv::IMWRITE_PNG_COMPRESSION, 0});
  const std::size_t idat = png.find("IDAT") - 4;
  const std::uint32_t idat_length = (static_cast<unsigned char>(png[idat + 2]) << 8) | static_cast<unsigned char>(png[idat + 3]);
  std::string damaged = png.substr(0, idat) + WithChunk(std::string(33, '\0'), "IDAT",
                                                         png.substr(idat + 8, idat_length / 2)).substr(33) +
                        png.substr(idat + 12 + idat_length);
  std::string bad_filter = png;  // stored (level 0) deflate: the first row's filter byte follows the block header
  bad_filter[idat + 8 + 2 + 5] = 9;
  bad_filter = bad_filter.substr(0, idat) + WithChunk(std::string(33, '\0'), "IDAT",
                                                      bad_filter.substr(idat + 8, idat_length)).substr(33) +
               bad_filter.substr(idat + 12 + idat_length);
  for (const std::string* file : {&damaged, &bad_filter}) {
    for (const int flags : {cv::IMREAD_UNCHANGED, cv::IMREAD_GRAYSCALE}) {
      const auto bytes = cv::Mat(1, static_cast<int>(file->size()), CV_8UC1, const_cast<char*>(file->data()));
      ::testing::internal::CaptureStderr();
      const cv::Mat opencv = cv::imdecode(bytes, flags);
      const std::string opencv_printed = ::testing::internal::GetCapturedStderr();
      ::testing::internal::CaptureStderr();
      const std::optional<cv::Mat> here = DecodeCommonPng(*file, flags);
      const std::string printed = ::testing::internal::GetCapturedStderr();
      EXPECT_TRUE(opencv.empty());
      ASSERT_TRUE(here.has_value());
      EXPECT_TRUE(here->empty());
      EXPECT_EQ(printed, opencv_printed);
      EXPECT_NE(printed.find("libpng error"), std::string::npos) << printed;
    }
  }
  // Left to OpenCV: transparency, EXIF, interlacing, a palette, 1-bit grey, another format, other flags.
  EXPECT_FALSE(DecodeCommonPng(WithChunk(grey, "tRNS", std::string("\x00\x07", 2)), cv::IMREAD_UNCHANGED));
  EXPECT_FALSE(DecodeCommonPng(WithChunk(grey, "eXIf", "MM"), cv::IMREAD_GRAYSCALE));
  const std::string ihdr = grey.substr(16, 13);
  for (const auto& [at, value] : {std::pair{12, '\x01'}, std::pair{9, '\x03'}, std::pair{8, '\x01'}}) {
    std::string changed = ihdr;
    changed[at] = value;
    EXPECT_FALSE(DecodeCommonPng(WithChunk(grey, "IHDR", changed), cv::IMREAD_UNCHANGED)) << at;
  }
  EXPECT_FALSE(DecodeCommonPng(Encode(Gradient(8, 8), ".jpg"), cv::IMREAD_GRAYSCALE));
  EXPECT_FALSE(DecodeCommonPng(grey, cv::IMREAD_COLOR));
}

// A PNG that declares 100 000 x 100 000 px in 60 bytes: refused from its header, before any decoding.
TEST(ImageFile, DecompressionBombsAreRefusedFromTheHeader) {
  std::string png = Encode(Gradient(8, 8), ".png");
  const auto put = [&](size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) png[at + static_cast<size_t>(i)] = static_cast<char>((v >> (24 - 8 * i)) & 0xFF);
  };
  put(16, 100000);
  put(20, 100000);
  const std::string why = ErrorOf([&] { DecodeImage(png, Channels::kGrey, "bomb.png"); });
  EXPECT_NE(why.find("bomb.png: 100000 x 100000 px is over the 250 Mpx"), std::string::npos) << why;
  // The limit is the caller's: a small one refuses an ordinary image, by file size or by pixels.
  ImageLimits small;
  small.max_pixels = 1000;
  EXPECT_NE(ErrorOf([&] { DecodeImage(Encode(Gradient(40, 40), ".jpg"), Channels::kGrey, "a.jpg", small); })
                .find("over the 0 Mpx"),
            std::string::npos);
}

TEST(ImageFile, EveryBadFileIsOneLineNamingIt) {
  const auto dir = std::filesystem::temp_directory_path() / fmt::format("topocal_imageio_{}", ::getpid());
  std::filesystem::create_directories(dir);
  const auto path = [&](const char* name) { return (dir / name).string(); };
  std::ofstream(path("text.png")) << "not an image";
  std::ofstream(path("empty.jpg"));
  const std::string jpeg = Encode(Gradient(200, 100), ".jpg");
  std::ofstream(path("truncated.jpg"), std::ios::binary) << jpeg.substr(0, 100);
  std::ofstream(path("good.jpg"), std::ios::binary) << jpeg;

  const auto expect = [&](const char* name, const char* fragment, const ImageLimits& limits = {}) {
    const std::string why = ErrorOf([&] { ReadImage(path(name), Channels::kGrey, limits); });
    EXPECT_EQ(why.rfind(path(name) + ": ", 0), 0u) << why;  // starts with the path
    EXPECT_NE(why.find(fragment), std::string::npos) << why;
    EXPECT_EQ(why.find('\n'), std::string::npos) << why;
  };
  expect("missing.png", "cannot be opened for reading: No such file");
  expect("text.png", "cannot be read as an image");
  expect("empty.jpg", "empty file");
  expect("truncated.jpg", "truncated JPEG");
  ImageLimits tiny;
  tiny.max_file_bytes = 1000;
  expect("good.jpg", "over the 0 MiB", tiny);
  // A device reads as an empty file.
  EXPECT_NE(ErrorOf([&] { ReadImage("/dev/null", Channels::kGrey); }).find("/dev/null: empty file"), std::string::npos);
  const cv::Mat good = ReadImage(path("good.jpg"), Channels::kGrey);
  EXPECT_EQ(good.cols, 200);
  EXPECT_NE(ErrorOf([&] { RequireSize(good, path("good.jpg"), 640, 480, "camera.json"); })
                .find("the image is 200 x 100 px but camera.json says 640 x 480 px"),
            std::string::npos);
  EXPECT_EQ(ErrorOf([&] { RequireSize(good, path("good.jpg"), 200, 100, "camera.json"); }), "");
  std::filesystem::remove_all(dir);
}

// Truncated or damaged files: refused with one line naming the file, and nothing else printed (libpng wrote
// "libpng error: ..." and OpenCV "imdecode_(''): can't read data: ..." to stderr before topocal's line; a JPEG cut
// short decoded into a whole image with grey rows).
TEST(ImageFile, TruncatedOrDamagedFilesAreRefusedAndNothingElseIsPrinted) {
  const std::string png = Encode(Gradient(300, 200), ".png");
  const std::string jpeg = Encode(Gradient(300, 200, CV_8UC3), ".jpg");
  const std::string progressive = Encode(Gradient(300, 200, CV_8UC3), ".jpg", {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
  const std::string pgm = Encode(Gradient(300, 200), ".pgm");
  std::vector<std::pair<std::string, std::string>> bad;  // (name, bytes)
  for (std::size_t cut = 33; cut < png.size(); cut += 1009) bad.push_back({fmt::format("cut{}.png", cut), png.substr(0, cut)});
  for (std::size_t cut = 200; cut < jpeg.size(); cut += 2003) bad.push_back({fmt::format("cut{}.jpg", cut), jpeg.substr(0, cut)});
  for (std::size_t cut = 400; cut < progressive.size(); cut += 3001) {
    bad.push_back({fmt::format("cut{}.progressive.jpg", cut), progressive.substr(0, cut)});
  }
  for (const std::size_t at : {std::size_t{18}, png.size() / 2, png.size() - 10}) {  // IHDR, IDAT, IEND's CRC
    std::string flipped = png;
    flipped[at] = static_cast<char>(flipped[at] ^ 0x20);
    bad.push_back({fmt::format("flip{}.png", at), flipped});
  }
  bad.push_back({"cut.pgm", pgm.substr(0, pgm.size() / 2)});
  for (const auto& [name, bytes] : bad) {
    SCOPED_TRACE(name);
    ::testing::internal::CaptureStderr();
    const std::string why = ErrorOf([&] { DecodeImage(bytes, Channels::kGrey, name); });
    const std::string printed = ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(why.rfind(name + ": ", 0), 0u) << why;
    EXPECT_EQ(why.find('\n'), std::string::npos) << why;
    EXPECT_EQ(printed, "");
  }
  // Whole files still decode, progressive JPEGs (several scans) included.
  for (const std::string* whole : {&png, &jpeg, &progressive, &pgm}) {
    EXPECT_EQ(DecodeImage(*whole, Channels::kGrey, "whole").cols, 300);
  }
}

// Encoding goes through the codec plugin: the bytes are OpenCV's own (what cv::imencode writes in this process,
// which links imgcodecs directly), so every PNG topocal wrote before the plugin is written the same.
TEST(ImageFile, EncodesPngByteForByteAsOpenCvDoes) {
  cv::Mat deep(37, 51, CV_16UC1);
  cv::randu(deep, 0, 65535);
  for (const cv::Mat& image : {Gradient(64, 48), Gradient(31, 7, CV_8UC3), Gradient(9, 5, CV_8UC4), deep}) {
    SCOPED_TRACE(fmt::format("type {} {}x{}", image.type(), image.cols, image.rows));
    const std::vector<unsigned char> png = EncodePng(image, "mem.png");
    EXPECT_EQ(std::string(png.begin(), png.end()), Encode(image, ".png"));
    const cv::Mat back = DecodeImage(std::string(png.begin(), png.end()), Channels::kAsStored, "mem.png");
    ASSERT_EQ(back.type(), image.type());
    EXPECT_EQ(cv::norm(back, image, cv::NORM_INF), 0.0);
  }
  const auto path = std::filesystem::temp_directory_path() / fmt::format("topocal_imageio_png_{}.png", ::getpid());
  WritePng(path.string(), deep);
  EXPECT_EQ(cv::norm(cv::imread(path.string(), cv::IMREAD_UNCHANGED), deep, cv::NORM_INF), 0.0);
  std::filesystem::remove(path);
  // What PNG cannot hold is refused with the output's name, never written.
  try {
    EncodePng(cv::Mat(4, 4, CV_8UC2, cv::Scalar(1, 2)), "two-channels.png");
    ADD_FAILURE() << "a two-channel image was encoded as PNG";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("two-channels.png: PNG encoding failed: ", 0), 0u) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace topocal::imageio
