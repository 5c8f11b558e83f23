#pragma once
// The container of an image file checked before its decoder sees it. libpng reports a truncated or damaged PNG by
// printing "libpng error: ..." to the process's stderr from inside OpenCV (no way to silence it from outside), and
// libjpeg decodes a JPEG cut short into a whole image whose missing rows are grey: so the framing of both is checked
// here, where a failure is one line naming the file.
//
//   PNG  (ISO/IEC 15948 §5): signature, then chunks (length, type, data, CRC-32 of type and data) up to IEND. Every
//        chunk must lie within the file and its CRC must match (zlib's crc32; libpng checks the same, but reports
//        through stderr).
//   JPEG (ITU-T T.81 §B): SOI, marker segments, entropy-coded scans (0xFF stuffed as 0xFF00; RSTn inside), up to
//        EOI. A file that ends before EOI is truncated.
// Other formats (PNM, TIFF, BMP, ...) are left to the decoder.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace topocal::imageio {

// Throws util::InputError "NAME: cannot be read as an image (truncated PNG: ...)" (or damaged PNG, truncated or
// damaged JPEG) when the bytes are a PNG or JPEG whose framing is broken; returns for anything else.
void CheckContainer(std::string_view bytes, const std::string& name);

// The 4-byte big-endian unsigned integer at `at` (PNG's lengths and sizes); the caller checks that it lies in b.
std::uint32_t BigEndian32(std::string_view b, std::size_t at);

}  // namespace topocal::imageio
