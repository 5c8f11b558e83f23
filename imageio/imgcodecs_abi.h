#pragma once
// The interface between imageio (image_file.cc) and its codec plugin (imgcodecs_plugin.cc, the MODULE library
// libtopocal_imgcodecs.so that links OpenCV's imgcodecs). Debian's libopencv_imgcodecs pulls in 112 shared libraries
// (GDAL, GDCM, poppler, HDF5, OpenEXR, ...), which cost every topocal process ~150 ms of dynamic loading whether it
// reads an image or not; behind this plugin only the processes that encode or decode an image load them, at their
// first image (docs/performance.md, "Start-up").
//
// One symbol with C linkage, kEntryPoint, returns the table below. The table's types are C++ (cv::Mat,
// std::vector): the plugin is built from the same tree against the same libopencv_core and libstdc++ as the program
// that loads it, which the loader checks through abi_version and opencv_version before using any other field.
// Nothing throws across the boundary: a failure returns false with a one-line message in `error`.
#include <cstddef>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace topocal::imageio {

// Raised whenever a field or a function's meaning changes.
inline constexpr int kImgcodecsAbiVersion = 2;
inline constexpr const char* kImgcodecsEntryPoint = "topocal_imgcodecs_api";

struct ImgcodecsApi {
  int abi_version;             // kImgcodecsAbiVersion of the plugin's build
  const char* opencv_version;  // CV_VERSION of the plugin's build
  // cv::imdecode(bytes, imread_flags) into *out (empty when OpenCV cannot decode the bytes: returns true, with the
  // decoder's message in `error` when it gave one; nothing is printed).
  bool (*decode)(const unsigned char* bytes, std::size_t size, int imread_flags, cv::Mat* out, char* error,
                 std::size_t error_size);
  // cv::imencode(extension, *image, *out, params[0..param_count)); false when OpenCV refuses or fails.
  bool (*encode)(const char* extension, const cv::Mat* image, const int* params, std::size_t param_count,
                 std::vector<unsigned char>* out, char* error, std::size_t error_size);
};

}  // namespace topocal::imageio

extern "C" {
// The plugin's one exported symbol (kImgcodecsEntryPoint).
using TopocalImgcodecsEntry = const topocal::imageio::ImgcodecsApi* (*)();
}
