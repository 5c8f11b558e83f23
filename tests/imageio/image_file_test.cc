// The one image loader and writer: headers probed right, bombs refused before decoding, every failure one line naming
// the file, PNGs encoded as OpenCV encodes them.
#include "imageio/image_file.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

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
