#pragma once
// The one image loader. Every image file topocal reads — calibration views, spot images, reference
// balls — goes through ReadImage, which
//  - names the file in every error (util::InputError, one line): missing, unreadable, too large, not an image,
//    truncated, or not the size the camera file says;
//  - refuses a file over max_file_bytes before reading it, and an image over max_pixels from its header before
//    decoding it (PNG and JPEG headers are read here; other formats are checked once decoded, under OpenCV's own
//    1 Gpx guard), so a decompression bomb costs neither the memory nor the time;
//  - catches every OpenCV and codec exception at the boundary.
// Decoding and encoding are OpenCV's (cv::imdecode, cv::imencode); only the header probe is written here, because
// OpenCV 4.6 has no call that reads an image's size without decoding it. This module is the only owner of image
// encoding and decoding in topocal: OpenCV's codecs live in a plugin (libtopocal_imgcodecs.so, imgcodecs_abi.h)
// loaded at the first image a process encodes, or decodes other than a common PNG (png_decode.h: those are decoded
// in process by OpenCV's own libpng calls), so that the processes that need no codec do not pay for the 112 shared
// libraries behind Debian's libopencv_imgcodecs (docs/performance.md, "Start-up"). The plugin is looked
// up as $TOPOCAL_IMGCODECS_PLUGIN (a file) if set, else at <executable>/../<libdir>/topocal/ (the installed layout,
// which the build tree mirrors), else at <the configured install prefix>/<libdir>/topocal/. When it cannot be
// loaded, the first image operation throws CodecsUnavailable naming the file and where it was looked for.
//
//   const cv::Mat grey = imageio::ReadImage(path, imageio::Channels::kGrey);
//   imageio::RequireSize(grey, path, camera.width_px, camera.height_px, "camera.json");
#include <cstdint>
#include <future>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace topocal::imageio {

enum class Channels {
  kGrey,      // one 8-bit channel (colour converted, 16-bit scaled) — what the detectors read
  kAsStored,  // channels and depth as in the file (cv::IMREAD_UNCHANGED)
};

struct ImageLimits {
  std::uint64_t max_file_bytes = std::uint64_t{1} << 30;  // 1 GiB
  // 250 Mpx: 6x the largest phone sensors of 2026 (~50 Mpx in full-resolution modes), 20x the demo unit's.
  std::int64_t max_pixels = 250'000'000;
};

struct StoredSize {
  int width_px = 0, height_px = 0;
};
// The image size a PNG or JPEG declares in its header; nullopt for other formats or when no header is found.
std::optional<StoredSize> ProbeStoredSize(std::string_view bytes) noexcept;

// Decodes an image held in memory; `name` names it in errors. Throws util::InputError.
cv::Mat DecodeImage(std::string_view bytes, Channels channels, const std::string& name, const ImageLimits& limits = {});
// An image file's bytes: a regular file mapped read-only, anything else (a pipe) read into memory. Mapping costs no
// fresh memory: on the 2-core development VM, where every new page costs ~20 us, reading the 17 MB reference sphere
// into a new buffer took ~90 ms and mapping it ~8 ms. The price of a mapping: a file truncated by another
// process while it is being decoded ends the process with SIGBUS (as for any program that maps its input).
class ImageBytes {
 public:
  ImageBytes() = default;
  explicit ImageBytes(std::string bytes) : owned_(std::move(bytes)) {}
  ~ImageBytes();
  ImageBytes(ImageBytes&& other) noexcept;
  ImageBytes& operator=(ImageBytes&& other) noexcept;
  ImageBytes(const ImageBytes&) = delete;
  ImageBytes& operator=(const ImageBytes&) = delete;
  std::string_view view() const noexcept;
  operator std::string_view() const noexcept { return view(); }  // NOLINT: bytes are used where a view is

 private:
  friend ImageBytes ReadImageBytes(const std::string& path, const ImageLimits& limits);
  void* map_ = nullptr;
  size_t map_size_ = 0;
  std::string owned_;
};

// An image file's bytes, undecoded, refused (util::InputError naming the path) when it cannot be read or is over
// limits.max_file_bytes (checked before reading a regular file, while streaming anything else). For callers that
// also hash the file (the unit record's provenance): read once, then Sha256Hex and DecodeImage on the same bytes.
ImageBytes ReadImageBytes(const std::string& path, const ImageLimits& limits = {});
// Reads and decodes an image file: DecodeImage(ReadImageBytes(path)). Throws util::InputError naming the path.
cv::Mat ReadImage(const std::string& path, Channels channels, const ImageLimits& limits = {});
// PNG bytes of `image` (8- or 16-bit; 1, 3 or 4 channels in OpenCV's BGR(A) order), OpenCV's encoder with its
// default settings (zlib level 1, SUB filter). `name` names the output in errors. Throws std::runtime_error.
std::vector<unsigned char> EncodePng(const cv::Mat& image, const std::string& name);
// EncodePng, then util::WriteFileAtomic(path).
void WritePng(const std::string& path, const cv::Mat& image);

// The codec plugin cannot be found or loaded (a broken installation, not bad input): one line naming the file.
class CodecsUnavailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
// Whether DecodeImage decodes these bytes without OpenCV's codecs (a PNG of the kinds png_decode.h decodes): a caller
// that would load the codecs ahead of its images needs them only when one is not.
bool DecodesWithoutCodecs(std::string_view bytes) noexcept;
// Starts loading the codecs on a thread of its own, for a caller with other work to do before its first image
// (~0.1 s of dynamic loading, mostly relocations). Never throws: a failure is reported by the first image
// operation. The returned future waits for the load when destroyed.
[[nodiscard]] std::future<void> LoadCodecsInBackground();

// Throws util::InputError unless `image` is width_px x height_px, naming the path and where the size comes from.
void RequireSize(const cv::Mat& image, const std::string& path, int width_px, int height_px, const std::string& source);

}  // namespace topocal::imageio
