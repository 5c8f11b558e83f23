#pragma once
// RAII ownership of libapriltag's C objects (private to calib/ and the programs that measure it against libapriltag:
// include only from .cc files; apriltag is a PRIVATE dependency of topocal::calib). Every object libapriltag
// allocates is freed by its own destroy function.
#include <cstdlib>
#include <memory>
#include <vector>

extern "C" {
#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/common/zarray.h>
#include <apriltag/tag36h11.h>
}

namespace topocal::calib::apriltag_raii {

struct FamilyDeleter {
  void operator()(apriltag_family_t* family) const noexcept { tag36h11_destroy(family); }
};
struct DetectorDeleter {
  void operator()(apriltag_detector_t* detector) const noexcept { apriltag_detector_destroy(detector); }
};
struct DetectionsDeleter {
  void operator()(zarray_t* detections) const noexcept { apriltag_detections_destroy(detections); }
};
// Debian's libapriltag3 (3.3.0) does not export image_u8_destroy; its body is free(buf) then free(image), both
// allocated with calloc by image_u8_create_stride (which apriltag_to_image uses), so free them the same way.
struct ImageDeleter {
  void operator()(image_u8_t* image) const noexcept {
    if (!image) return;
    std::free(image->buf);
    std::free(image);
  }
};

using Tag36h11Family = std::unique_ptr<apriltag_family_t, FamilyDeleter>;
using Detector = std::unique_ptr<apriltag_detector_t, DetectorDeleter>;
using Detections = std::unique_ptr<zarray_t, DetectionsDeleter>;
using Image = std::unique_ptr<image_u8_t, ImageDeleter>;

inline Tag36h11Family MakeTag36h11() { return Tag36h11Family(tag36h11_create()); }

// Kalibr prints the tag36h11 codes inside a 2-cell black border (calib/target.h). libapriltag's decoder takes the
// layout from the family struct, not from code: the quad's corners are (0, 0) and (width_at_border,
// width_at_border) in bit cells, it learns black and white from the cells half a cell inside and outside the quad's
// edge, and reads bit i at the centre of cell (bit_x[i], bit_y[i]); total_width (the tag with its white ring) sizes
// the grid of bit values it sharpens. So the same codes behind one more black ring are a fresh tag36h11 instance
// with width_at_border 8 -> 10, total_width 10 -> 12 and every bit one cell further in. The arrays are this
// instance's own (tag36h11_create allocates them), and tag36h11_destroy frees them as usual.
inline Tag36h11Family MakeKalibrTag36h11() {
  Tag36h11Family family(tag36h11_create());
  if (!family) return family;
  family->width_at_border += 2;
  family->total_width += 2;
  for (uint32_t i = 0; i < family->nbits; ++i) {
    ++family->bit_x[i];
    ++family->bit_y[i];
  }
  return family;
}

// The bitmap of one code without libapriltag's outer white ring: width_at_border^2 cells, row-major, y down,
// 1 = black (the outermost ring is the black border).
inline std::vector<uint8_t> TagBitmap(apriltag_family_t* family, int code, int* cells) {
  const Image image(apriltag_to_image(family, code));
  const int border = (family->total_width - family->width_at_border) / 2;
  *cells = family->width_at_border;
  std::vector<uint8_t> bits(static_cast<size_t>(*cells * *cells));
  for (int y = 0; y < *cells; ++y) {
    for (int x = 0; x < *cells; ++x) {
      bits[static_cast<size_t>(y * *cells + x)] = image->buf[(y + border) * image->stride + x + border] < 128;
    }
  }
  return bits;
}

}  // namespace topocal::calib::apriltag_raii
