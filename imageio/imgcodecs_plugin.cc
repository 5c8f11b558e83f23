// libtopocal_imgcodecs.so: OpenCV's image codecs behind the C-linkage table of imgcodecs_abi.h, loaded by imageio
// at its first image (image_file.cc). Only imageio loads it; nothing else links opencv_imgcodecs.
#include <cstdio>
#include <exception>
#include <iostream>
#include <streambuf>
#include <string>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "imageio/imgcodecs_abi.h"

namespace {

using topocal::imageio::ImgcodecsApi;

void SetError(char* error, std::size_t error_size, const char* what) {
  if (error_size > 0) std::snprintf(error, error_size, "%s", what);
}

// OpenCV's imdecode reports a decoder's failure by writing to std::cerr ("imdecode_(''): can't read data: ...") and
// returning an empty image: its text would precede topocal's one line. std::cerr is routed through this buffer once
// the plugin is loaded: on a thread inside Decode the text is kept for the error message; on any other thread it
// goes on to the original buffer unchanged (the buffer holds no characters itself, so threads do not share state).
thread_local std::string* t_captured = nullptr;

class DecoderMessages : public std::streambuf {
 public:
  explicit DecoderMessages(std::streambuf* original) : original_(original) {}

 protected:
  int overflow(int c) override {
    if (c == traits_type::eof()) return traits_type::not_eof(c);
    if (t_captured) {
      t_captured->push_back(static_cast<char>(c));
      return c;
    }
    return original_->sputc(static_cast<char>(c));
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    if (t_captured) {
      t_captured->append(s, static_cast<std::size_t>(n));
      return n;
    }
    return original_->sputn(s, n);
  }
  int sync() override { return t_captured ? 0 : original_->pubsync(); }

 private:
  std::streambuf* original_;
};

void CaptureDecoderMessages() {
  static DecoderMessages* const messages = [] {
    auto* m = new DecoderMessages(std::cerr.rdbuf());  // lives as long as the process: std::cerr may outlive us
    std::cerr.rdbuf(m);
    return m;
  }();
  (void)messages;
}

// The decoder's message on one line, without OpenCV's "imdecode_(''): " prefix and its source location.
std::string OneLine(std::string text) {
  for (const std::string& prefix : {std::string("imdecode_(''): "), std::string("can't read data: ")}) {
    if (text.rfind(prefix, 0) == 0) text.erase(0, prefix.size());
  }
  if (const auto at = text.find("error: ("); at != std::string::npos) {
    if (const auto close = text.find(") ", at); close != std::string::npos) text.erase(0, close + 2);
  }
  if (const auto in = text.find(" in function "); in != std::string::npos) text.erase(in);
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

bool Decode(const unsigned char* bytes, std::size_t size, int imread_flags, cv::Mat* out, char* error,
            std::size_t error_size) {
  CaptureDecoderMessages();
  std::string captured;
  struct Capture {
    explicit Capture(std::string* s) { t_captured = s; }
    ~Capture() { t_captured = nullptr; }
  };
  try {
    const cv::Mat buffer(1, static_cast<int>(size), CV_8UC1, const_cast<unsigned char*>(bytes));
    {
      const Capture capture(&captured);
      *out = cv::imdecode(buffer, imread_flags);
    }
    if (out->empty() && !captured.empty()) SetError(error, error_size, OneLine(captured).c_str());
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
