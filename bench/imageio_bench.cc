// Decoding the PNGs a unit and a capture read: topocal's in-process decoder (imageio/png_decode.h: libdeflate and the
// PNG row filters for plain files) against cv::imdecode (libpng and zlib, what OpenCV and the decoder's fallback use)
// on the same bytes: a noisy 4000 x 3000 frame of 16-bit grey (the reference sphere's spot image) and of 8-bit grey
// (the target view), each written as OpenCV writes it.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "imageio/large_buffers.h"
#include "imageio/png_decode.h"

namespace {

// Both decoders with the image buffers the CLI has (huge pages, imageio/large_buffers.h).
std::string NoisyPng(int depth) {
  topocal::imageio::UseHugePagesForImageBuffers();
  cv::Mat image(3000, 4000, CV_MAKETYPE(depth, 1));
  cv::RNG rng(1);  // seeded: the same bytes every run
  // A dark background with sensor noise, as a spot image's pixels mostly are.
  rng.fill(image, cv::RNG::NORMAL, depth == CV_16U ? 3000 : 20, depth == CV_16U ? 400 : 3);
  std::vector<unsigned char> bytes;
  cv::imencode(".png", image, bytes);
  return std::string(bytes.begin(), bytes.end());
}

void BM_DecodePng_Topocal(benchmark::State& state) {
  const std::string png = NoisyPng(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(topocal::imageio::DecodeCommonPng(png, cv::IMREAD_UNCHANGED));
  state.SetLabel(state.range(0) == CV_16U ? "16-bit grey" : "8-bit grey");
}
BENCHMARK(BM_DecodePng_Topocal)->Arg(CV_16U)->Arg(CV_8U)->Unit(benchmark::kMillisecond);

void BM_DecodePng_OpenCvImdecode(benchmark::State& state) {
  const std::string png = NoisyPng(static_cast<int>(state.range(0)));
  const cv::Mat bytes(1, static_cast<int>(png.size()), CV_8UC1, const_cast<char*>(png.data()));
  for (auto _ : state) benchmark::DoNotOptimize(cv::imdecode(bytes, cv::IMREAD_UNCHANGED));
  state.SetLabel(state.range(0) == CV_16U ? "16-bit grey (peer)" : "8-bit grey (peer)");
}
BENCHMARK(BM_DecodePng_OpenCvImdecode)->Arg(CV_16U)->Arg(CV_8U)->Unit(benchmark::kMillisecond);

}  // namespace
