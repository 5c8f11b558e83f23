// libFuzzer target: the one image loader (imageio::DecodeImage, what ReadImage runs on a file's bytes). Any input
// must give an image or a util::InputError, never a crash, a hang or an allocation beyond the pixel limit.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "imageio/image_file.h"
#include "util/io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace topocal;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  imageio::ImageLimits limits;
  limits.max_pixels = 4'000'000;  // keeps each run fast; the header check is what is fuzzed
  (void)imageio::ProbeStoredSize(bytes);
  for (const auto channels : {imageio::Channels::kGrey, imageio::Channels::kAsStored}) {
    try {
      const auto image = imageio::DecodeImage(bytes, channels, "fuzz-input", limits);
      if (image.empty() || static_cast<std::int64_t>(image.total()) > limits.max_pixels) __builtin_trap();
    } catch (const util::InputError&) {
    }
  }
  return 0;
}
