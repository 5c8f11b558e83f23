// libtopocal_imgcodecs.so: OpenCV's image codecs behind the C-linkage table of imgcodecs_abi.h, loaded by imageio
// at its first image (image_file.cc). Only imageio loads it; nothing else links opencv_imgcodecs.
#include <cstdio>
#include <exception>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "imageio/imgcodecs_abi.h"

namespace {

using topocal::imageio::ImgcodecsApi;

void SetError(char* error, std::size_t error_size, const char* what) {
  if (error_size > 0) std::snprintf(error, error_size, "%s", what);
}

bool Decode(const unsigned char* bytes, std::size_t size, int imread_flags, cv::Mat* out, char* error,
            std::size_t error_size) {
  try {
    const cv::Mat buffer(1, static_cast<int>(size), CV_8UC1, const_cast<unsigned char*>(bytes));
    *out = cv::imdecode(buffer, imread_flags);
    return true;
  } catch (const cv::Exception& e) {
    SetError(error, error_size, e.err.c_str());
  } catch (const std::exception& e) {  // std::bad_alloc from a codec and the like
    SetError(error, error_size, e.what());
  } catch (...) {
    SetError(error, error_size, "unknown exception in the image decoder");
  }
  return false;
}

bool Encode(const char* extension, const cv::Mat* image, const int* params, std::size_t param_count,
            std::vector<unsigned char>* out, char* error, std::size_t error_size) {
  try {
    if (cv::imencode(extension, *image, *out, std::vector<int>(params, params + param_count))) return true;
    SetError(error, error_size, "the encoder refused the image");
  } catch (const cv::Exception& e) {
    SetError(error, error_size, e.err.c_str());
  } catch (const std::exception& e) {
    SetError(error, error_size, e.what());
  } catch (...) {
    SetError(error, error_size, "unknown exception in the image encoder");
  }
  return false;
}

constexpr ImgcodecsApi kApi{topocal::imageio::kImgcodecsAbiVersion, CV_VERSION, &Decode, &Encode};

}  // namespace

extern "C" __attribute__((visibility("default"))) const ImgcodecsApi* topocal_imgcodecs_api() { return &kApi; }
