#include "imageio/image_file.h"

#include <dlfcn.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>  // the IMREAD_ and IMWRITE_ constants only: the codecs are the plugin's
#include <stdexcept>
#include <utility>
#include <vector>

#include "imageio/container_check.h"
#include "imageio/imgcodecs_abi.h"
#include "imageio/png_decode.h"
#include "util/io.h"

namespace topocal::imageio {
namespace {

// The plugin, loaded once per process (a function-local static: concurrent first uses wait for one load).
struct LoadedCodecs {
  const ImgcodecsApi* api = nullptr;
  std::string error;  // why api is null
};

std::vector<std::string> PluginCandidates() {
  namespace fs = std::filesystem;
  if (const char* env = std::getenv("TOPOCAL_IMGCODECS_PLUGIN"); env && *env) return {env};
  std::vector<std::string> candidates;
  std::error_code ec;
  // The installed layout, relative to the executable (a moved install keeps working), which the build tree mirrors
  // for build/tools and build/bench (imageio/CMakeLists.txt).
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    candidates.push_back(
        (exe.parent_path().parent_path() / TOPOCAL_INSTALL_LIBDIR / "topocal" / TOPOCAL_IMGCODECS_FILE).string());
  }
  // Programs linking the installed libraries live anywhere: the prefix topocal was configured to install into.
  const std::string installed = fmt::format("{}/topocal/{}", TOPOCAL_INSTALL_FULL_LIBDIR, TOPOCAL_IMGCODECS_FILE);
  if (std::find(candidates.begin(), candidates.end(), installed) == candidates.end()) candidates.push_back(installed);
  return candidates;
}

LoadedCodecs LoadCodecsNow() {
  LoadedCodecs loaded;
  const auto candidates = PluginCandidates();
  const auto it = std::find_if(candidates.begin(), candidates.end(),
                               [](const std::string& c) { return std::filesystem::exists(c); });
  if (it == candidates.end()) {
    loaded.error = fmt::format(
        "the image codecs plugin {} is not installed: not found at {} (install topocal with `cmake --install`, or "
        "set TOPOCAL_IMGCODECS_PLUGIN to the file)",
        TOPOCAL_IMGCODECS_FILE, fmt::join(candidates, ", "));
    return loaded;
  }
  // RTLD_LAZY: functions of the 112 libraries behind imgcodecs are bound when first called, not all at load.
  void* handle = dlopen(it->c_str(), RTLD_LAZY | RTLD_LOCAL);
  if (!handle) {
    loaded.error = fmt::format("{}: cannot load the image codecs plugin: {}", *it, dlerror());
    return loaded;
  }
  // Never dlclose'd: OpenCV's codecs keep state (and threads' keys) for the life of the process.
  const auto entry = reinterpret_cast<TopocalImgcodecsEntry>(dlsym(handle, kImgcodecsEntryPoint));
  const ImgcodecsApi* api = entry ? entry() : nullptr;
  if (!api) {
    loaded.error = fmt::format("{}: not a topocal image codecs plugin (no {})", *it, kImgcodecsEntryPoint);
  } else if (api->abi_version != kImgcodecsAbiVersion || std::strcmp(api->opencv_version, CV_VERSION) != 0) {
    loaded.error = fmt::format(
        "{}: an image codecs plugin of another build (interface {}, OpenCV {}; this program needs {}, OpenCV {})", *it,
        api->abi_version, api->opencv_version, kImgcodecsAbiVersion, CV_VERSION);
  } else {
    loaded.api = api;
  }
  return loaded;
}

const LoadedCodecs& Loaded() {
  static const LoadedCodecs loaded = LoadCodecsNow();
  return loaded;
}

const ImgcodecsApi& Codecs() {
  const LoadedCodecs& loaded = Loaded();
  if (!loaded.api) throw CodecsUnavailable(loaded.error);
  return *loaded.api;
}

std::uint32_t BigEndian(std::string_view b, size_t at, int bytes) noexcept {
  std::uint32_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | static_cast<unsigned char>(b[at + static_cast<size_t>(i)]);
  return v;
}

std::optional<StoredSize> ProbePng(std::string_view b) noexcept {
  // Signature (8 bytes), then the IHDR chunk: length (4), "IHDR", width (4), height (4), all big-endian.
  static constexpr std::string_view kSignature("\x89PNG\r\n\x1a\n", 8);
  if (b.size() < 24 || b.substr(0, 8) != kSignature || b.substr(12, 4) != "IHDR") return std::nullopt;
  const std::uint32_t w = BigEndian(b, 16, 4), h = BigEndian(b, 20, 4);
  // PNG limits both to 2^31 - 1; larger values are malformed, reported as "too large" by the caller.
  return StoredSize{static_cast<int>(std::min<std::uint32_t>(w, 0x7fffffff)), static_cast<int>(std::min<std::uint32_t>(h, 0x7fffffff))};
}

std::optional<StoredSize> ProbeJpeg(std::string_view b) noexcept {
  // SOI, then marker segments (0xFF, code, big-endian length including itself) up to a start-of-frame marker
  // (0xC0-0xCF except DHT 0xC4, JPG 0xC8, DAC 0xCC): precision (1), height (2), width (2).
  if (b.size() < 4 || static_cast<unsigned char>(b[0]) != 0xFF || static_cast<unsigned char>(b[1]) != 0xD8) return std::nullopt;
  size_t at = 2;
  while (at + 4 <= b.size()) {
    if (static_cast<unsigned char>(b[at]) != 0xFF) return std::nullopt;
    const unsigned char code = static_cast<unsigned char>(b[at + 1]);
    if (code == 0xFF) {  // fill byte
      ++at;
      continue;
    }
    if (code == 0xD8 || code == 0x01 || (code >= 0xD0 && code <= 0xD7)) {  // markers without a length
      at += 2;
      continue;
    }
    const std::uint32_t length = BigEndian(b, at + 2, 2);
    if (length < 2) return std::nullopt;
    if (code >= 0xC0 && code <= 0xCF && code != 0xC4 && code != 0xC8 && code != 0xCC) {
      if (at + 9 > b.size()) return std::nullopt;
      return StoredSize{static_cast<int>(BigEndian(b, at + 7, 2)), static_cast<int>(BigEndian(b, at + 5, 2))};
    }
    if (code == 0xDA || code == 0xD9) return std::nullopt;  // scan data or end before a frame header
    at += 2 + length;
  }
  return std::nullopt;
}

void CheckPixels(std::int64_t width, std::int64_t height, const std::string& name, const ImageLimits& limits) {
  if (width <= 0 || height <= 0)
    throw util::InputError(fmt::format("{}: the image declares a size of {} x {} px", name, width, height));
  if (width * height > limits.max_pixels) {
    throw util::InputError(fmt::format("{}: {} x {} px is over the {} Mpx an image may have", name, width, height,
                                       limits.max_pixels / 1'000'000));
  }
}

}  // namespace

std::optional<StoredSize> ProbeStoredSize(std::string_view bytes) noexcept {
  if (auto png = ProbePng(bytes)) return png;
  return ProbeJpeg(bytes);
}

cv::Mat DecodeImage(std::string_view bytes, Channels channels, const std::string& name, const ImageLimits& limits) {
  if (bytes.empty()) throw util::InputError(fmt::format("{}: empty file, not an image", name));
  if (bytes.size() > limits.max_file_bytes) {
    throw util::InputError(
        fmt::format("{}: over the {} MiB an image file may have", name, limits.max_file_bytes >> 20));
  }
  if (const auto stored = ProbeStoredSize(bytes)) CheckPixels(stored->width_px, stored->height_px, name, limits);
  CheckContainer(bytes, name);
  const int flags = channels == Channels::kGrey ? cv::IMREAD_GRAYSCALE : cv::IMREAD_UNCHANGED;
  cv::Mat image;
  char error[512] = "";
  // The common PNGs in this process (png_decode.h), the rest through the plugin: the same pixels and messages.
  std::optional<cv::Mat> common;
  try {
    common = DecodeCommonPng(bytes, flags);
  } catch (const cv::Exception& e) {  // as the plugin reports OpenCV's exceptions
    throw util::InputError(fmt::format("{}: cannot be read as an image ({})", name, e.err));
  } catch (const std::exception& e) {
    throw util::InputError(fmt::format("{}: cannot be read as an image ({})", name, e.what()));
  }
  if (common) {
    image = std::move(*common);
  } else if (!Codecs().decode(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), flags, &image,
                              error, sizeof error)) {
    throw util::InputError(fmt::format("{}: cannot be read as an image ({})", name, error));
  }
  if (image.empty()) {
    throw util::InputError(fmt::format("{}: cannot be read as an image ({})", name,
                                       *error ? error : "not a format OpenCV decodes, or truncated"));
  }
  CheckPixels(image.cols, image.rows, name, limits);
  return image;
}

ImageBytes::~ImageBytes() {
  if (map_) munmap(map_, map_size_);
}

ImageBytes::ImageBytes(ImageBytes&& other) noexcept
    : map_(std::exchange(other.map_, nullptr)), map_size_(std::exchange(other.map_size_, 0)),
      owned_(std::move(other.owned_)) {}

ImageBytes& ImageBytes::operator=(ImageBytes&& other) noexcept {
  if (this != &other) {
    if (map_) munmap(map_, map_size_);
    map_ = std::exchange(other.map_, nullptr);
    map_size_ = std::exchange(other.map_size_, 0);
    owned_ = std::move(other.owned_);
  }
  return *this;
}

std::string_view ImageBytes::view() const noexcept {
  return map_ ? std::string_view(static_cast<const char*>(map_), map_size_) : std::string_view(owned_);
}

ImageBytes ReadImageBytes(const std::string& path, const ImageLimits& limits) {
  const auto too_large = [&] {
    return util::InputError(
        fmt::format("{}: over the {} MiB an image file may have", path, limits.max_file_bytes >> 20));
  };
  util::NoteInput(path);  // an output of this run may not be written over it
  // A regular file of known size is refused before reading and otherwise mapped whole (ImageBytes).
  {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw util::InputError(fmt::format("{}: cannot be opened for reading: {}", path, std::strerror(errno)));
    struct stat st {};
    const bool regular = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0;
    if (regular && static_cast<std::uint64_t>(st.st_size) > limits.max_file_bytes) {
      ::close(fd);
      throw too_large();
    }
    void* map = regular ? ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0)
                        : MAP_FAILED;
    ::close(fd);
    if (map != MAP_FAILED) {
      ImageBytes bytes;
      bytes.map_ = map;
      bytes.map_size_ = static_cast<size_t>(st.st_size);
      return bytes;
    }
  }
  // Anything else (a pipe, a device, a file that cannot be mapped) is read.
  std::ifstream in(path, std::ios::binary);
  if (!in) throw util::InputError(fmt::format("{}: cannot be opened for reading: {}", path, std::strerror(errno)));
  std::string bytes;
  // Anything else (a pipe), and whatever a file grew by while being read: read at most one byte more than allowed,
  // so that a stream over the limit is refused without reading it all.
  std::vector<char> chunk(1 << 20);
  while (in) {
    in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    bytes.append(chunk.data(), static_cast<size_t>(in.gcount()));
    if (bytes.size() > limits.max_file_bytes) throw too_large();
  }
  if (in.bad()) throw util::InputError(fmt::format("{}: read error", path));
  return ImageBytes(std::move(bytes));
}

cv::Mat ReadImage(const std::string& path, Channels channels, const ImageLimits& limits) {
  return DecodeImage(ReadImageBytes(path, limits), channels, path, limits);
}

std::vector<unsigned char> EncodePng(const cv::Mat& image, const std::string& name) {
  if (image.empty()) throw util::InputError(fmt::format("{}: no image to encode", name));
  const ImgcodecsApi& codecs = Codecs();
  std::vector<unsigned char> png;
  char error[512] = "";
  if (!codecs.encode(".png", &image, nullptr, 0, &png, error, sizeof error)) {
    throw std::runtime_error(fmt::format("{}: PNG encoding failed: {}", name, error));
  }
  return png;
}

void WritePng(const std::string& path, const cv::Mat& image) {
  const auto png = EncodePng(image, path);
  util::WriteFileAtomic(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

bool DecodesWithoutCodecs(std::string_view bytes) noexcept { return IsInProcessPng(bytes); }

std::future<void> LoadCodecsInBackground() {
  return std::async(std::launch::async, [] { Loaded(); });
}

void RequireSize(const cv::Mat& image, const std::string& path, int width_px, int height_px, const std::string& source) {
  if (image.cols != width_px || image.rows != height_px) {
    throw util::InputError(fmt::format("{}: the image is {} x {} px but {} says {} x {} px", path, image.cols,
                                       image.rows, source, width_px, height_px));
  }
}

}  // namespace topocal::imageio
